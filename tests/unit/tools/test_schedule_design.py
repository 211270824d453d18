"""tools/schedule_design.py: the design model against the margins the nonlinear law measured
with the paper's gains, and the committed schedule against the design's own targets."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.control.schedule_data import load_schedule
from tools import schedule_design as D

TAB = load_schedule()


def _margins(g: dict, kp: float):
    m = D.margins(D.open_loop({k: np.array([[v]]) for k, v in g.items()}, 1j * D.OMEGA, kp))
    return {k: float(v[0]) for k, v in m.items()}


def test_design_model_predicts_the_measured_margins_of_the_papers_gains():
    """docs/margins.md s. 2 measured, paper's gains, paper's case (k_p 0.8): crossover
    10.5-11.7 rad/s, phase margin 12-20 deg, all-channel delay margin 20 ms, downward gain
    margin about trim 3.1-6.0 dB."""
    m = _margins(D.PAPER_GAINS, 0.8)
    assert 10.0 < m["wc"] < 12.5
    assert 10.0 < m["pm_deg"] < 20.0
    assert 0.017 < m["dm_s"] < 0.024
    assert 3.0 < m["gm_down_db"] < 6.5
    assert not D.margins_ok({k: np.array([v]) for k, v in
                             {**m, "peak": 1.0, "bw_rad_s": 5.0}.items()})[0]


def test_a_pure_delay_lowers_the_models_phase_by_omega_tau():
    """The margins() reader on a loop with a known answer: k e^(-s T) / s has its crossover
    at k and phase margin 90 deg - k T (deg)."""
    k, tau = 4.0, 0.1
    lw = k * np.exp(-1j * D.OMEGA * tau) / (1j * D.OMEGA)
    m = D.margins(lw[None, :])
    assert float(m["wc"][0]) == pytest.approx(k, rel=0.01)
    assert float(m["pm_deg"][0]) == pytest.approx(90.0 - math.degrees(k * tau), abs=0.5)
    assert float(m["dm_s"][0]) == pytest.approx(math.radians(90.0 - math.degrees(k * tau)) / k,
                                                rel=0.02)


@pytest.mark.parametrize("i", range(len(TAB["qbar_kpa"])))
def test_every_committed_node_meets_the_design_targets(i):
    g = {"kappa1": TAB["kappa1"][i], "K": TAB["K"][i], "kappa2": TAB["kappa2"][i],
         "c": TAB["dob_c"][i], "cf_wn": TAB["cf_wn"][i], "flt_rate_hz": TAB["flt_rate_hz"][i],
         "flt_ang_hz": TAB["flt_ang_hz"][i]}
    ev = D.evaluate({k: np.array([v]) for k, v in g.items()})
    assert D.margins_ok(ev)[0], {k: float(v[0]) for k, v in ev.items()}
    assert ev["pm_deg"][0] >= D.PM_MIN_DEG and ev["dm_s"][0] >= D.DM_MIN_S
    assert TAB["omc_max_deg_s"][i] >= D.OMC_RANGE_DEG_S[0]
    assert np.all(np.diff(TAB["omc_max_deg_s"]) >= 0)      # more authority, more rate
