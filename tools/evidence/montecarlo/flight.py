"""What a campaign backend returns for one variant of one case: ``Flight``.

Its own module so that the backends (``apply``, ``hil``) and ``case``, which calls them, do
not import each other.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Flight:
    """What a backend returns for one variant of one case (SI).

    t_s : (n,) times; alpha_rad, beta_rad, mu_rad : (n,) true aerodynamic angles;
    cmd_t_s : (k,) command timeline times; cmd_rad : (k, 3) alpha, beta, mu commands;
    diverged : the backend's own verdict (the metrics' is OR-ed in);
    surfaces : tools.sitl.metrics.surface_figures of the flight (None: not available);
    full : anything else the backend produced (for ``rerun``), not stored in rows.
    """

    t_s: np.ndarray
    alpha_rad: np.ndarray
    beta_rad: np.ndarray
    mu_rad: np.ndarray
    cmd_t_s: np.ndarray
    cmd_rad: np.ndarray
    diverged: bool = False
    surfaces: dict | None = None
    full: object = None
