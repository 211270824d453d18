"""Eq. 3: the attitude kinematics Omega_dot = g_s omega (+ f1), g_s, its inverse and transpose.

Omega = [alpha, beta, mu] (rad), omega = [p, q, r] (rad/s). det g_s = -sec(beta); cos(beta)
is floored at COS_MIN where g_s divides by it. The plain functions return 3-tuples (no
scratch); the ``*_apply`` forms write them into an array (tests, tools).
"""
from __future__ import annotations

import math

from numba import njit

from fc.control.linalg3 import put3
from fc.control.nominal import COS_MIN


@njit(cache=True, inline="always", error_model="numpy")
def gs_inv(alpha_rad, beta_rad, v0, v1, v2):
    """g_s^-1 v, with g_s^-1 = [[0, sin a, cos a cos b], [1, 0, sin b], [0, -cos a, sin a cos b]]."""
    sin_alpha = math.sin(alpha_rad)
    cos_alpha = math.cos(alpha_rad)
    sin_beta = math.sin(beta_rad)
    cos_beta = math.cos(beta_rad)
    return (sin_alpha * v1 + cos_alpha * cos_beta * v2,
            v0 + sin_beta * v2,
            -cos_alpha * v1 + sin_alpha * cos_beta * v2)


@njit(cache=True, inline="always", error_model="numpy")
def gs(alpha_rad, beta_rad, w0, w1, w2):
    """g_s w (Eq. 3)."""
    sin_alpha = math.sin(alpha_rad)
    cos_alpha = math.cos(alpha_rad)
    cos_beta = max(math.cos(beta_rad), COS_MIN)
    tan_beta = math.sin(beta_rad) / cos_beta
    return (-cos_alpha * tan_beta * w0 + w1 - sin_alpha * tan_beta * w2,
            sin_alpha * w0 - cos_alpha * w2,
            (cos_alpha * w0 + sin_alpha * w2) / cos_beta)


@njit(cache=True, inline="always", error_model="numpy")
def gs_t(alpha_rad, beta_rad, s0, s1, s2):
    """g_s^T s (g_s of Eq. 3), the cross term of Eq. 35."""
    sin_alpha = math.sin(alpha_rad)
    cos_alpha = math.cos(alpha_rad)
    cos_beta = max(math.cos(beta_rad), COS_MIN)
    tan_beta = math.sin(beta_rad) / cos_beta
    return (-cos_alpha * tan_beta * s0 + sin_alpha * s1 + cos_alpha / cos_beta * s2,
            s0,
            -sin_alpha * tan_beta * s0 - cos_alpha * s1 + sin_alpha / cos_beta * s2)


@njit(cache=True, error_model="numpy")
def gs_inv_apply(alpha, beta, v0, v1, v2, out, o):
    """out[o:o+3] = g_s^-1 v (gs_inv)."""
    put3(out, o, gs_inv(alpha, beta, v0, v1, v2))


@njit(cache=True, error_model="numpy")
def gs_apply(alpha, beta, w0, w1, w2, out, o):
    """out[o:o+3] = g_s w (gs)."""
    put3(out, o, gs(alpha, beta, w0, w1, w2))


@njit(cache=True, error_model="numpy")
def gs_t_apply(alpha, beta, s0, s1, s2, out, o):
    """out[o:o+3] = g_s^T s (gs_t)."""
    put3(out, o, gs_t(alpha, beta, s0, s1, s2))
