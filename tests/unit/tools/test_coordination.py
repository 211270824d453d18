"""tools/evidence/coordination.py: the study's switches reach the law (issue 15, point 2)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fc.control.law import AttitudeLaw
from fc.control.layout import E_N
from tools.evidence import coordination as C

# a state with every term of the factors non-zero: alpha, beta, mu, p, q, r, V, h, gamma
EST = np.array([math.radians(4.0), math.radians(3.0), 0.0, 0.05, -0.04, 0.03, 2200.0,
                21000.0, 0.0])


def _lambdas(cfg: C.Config) -> tuple[float, float, float]:
    ov = cfg.overrides()
    ov["CO_ENABLE"] = 1.0 if cfg.coordinated else 0.0
    law = AttitudeLaw(ov)
    est = EST.copy()
    assert est.shape == (E_N,)
    law.reset(est)
    law.slow_step(est, (math.radians(5.0), 0.0, math.radians(4.0)), 0.01)
    law.fast_step(est, 0.002)
    s = law.status_dict()
    return s["lambda_e"], s["lambda_a"], s["lambda_r"]


@pytest.mark.parametrize("reading", ["eq14", "eq19"])
def test_each_factor_switch_turns_on_exactly_its_factor(reading):
    le, la, lr = _lambdas(C.Config("all", reading, "pos", 3.0))
    assert le != 0.0 and la != 0.0 and lr != 0.0
    assert _lambdas(C.Config("none", reading, "pos", 3.0)) == (0.0, 0.0, 0.0)
    assert _lambdas(C.Config("e_only", reading, "pos", 3.0)) == (le, 0.0, 0.0)
    assert _lambdas(C.Config("a_only", reading, "pos", 3.0)) == (0.0, la, 0.0)
    assert _lambdas(C.Config("r_only", reading, "pos", 3.0)) == (0.0, 0.0, lr)
    assert _lambdas(C.Config("no_a", reading, "pos", 3.0)) == (le, 0.0, lr)
    assert _lambdas(C.Config("E_only", reading, "pos", 3.0)) == (0.0, 0.0, 0.0)


def test_readings_set_the_factor_equation_explicitly():
    """Eq. 14 and Eq. 19 differ in the rate of lambda_e / lambda_a (p vs q, r vs p), and the
    k8 = k9 = 0 reading drops lambda_r3 = k8 beta + k9 q."""
    e14 = _lambdas(C.Config("all", "eq14", "pos", 3.0))
    e19 = _lambdas(C.Config("all", "eq19", "pos", 3.0))
    k0 = _lambdas(C.Config("all", "eq19_k89_0", "pos", 3.0))
    a, b, p, q, r = EST[0], EST[1], EST[3], EST[4], EST[5]
    assert e14[0] == pytest.approx(a + p) and e19[0] == pytest.approx(a + q)
    assert e14[1] == pytest.approx(b + r) and e19[1] == pytest.approx(b + p)
    assert e19[2] - k0[2] == pytest.approx(b + q)
    for name, ov in C.READINGS.items():
        assert {"CO_FAC_EQ", "CO_K8", "CO_K9", "DOB_ACHIEVED"} <= set(ov), name


def test_the_limit_and_the_observer_input_reach_the_law():
    law = AttitudeLaw(C.Config("all", "eq14_dobMc", "neg", 5.0).overrides())
    assert law.get_param("SLW_OMC_MAX") == 5.0
    assert law.get_param("DOB_ACHIEVED") == 0.0


def test_signed_scenario_mirrors_sideslip_and_bank_command():
    from plant_sim.scenario import load
    base = load("paper")
    neg = C.signed_scenario(base, "neg")
    assert neg.data["initial"]["beta_deg"] == -5.0
    assert [c[3] for c in neg.commands] == [-abs(c[3]) for c in base.commands]
    assert [c[1] for c in neg.commands] == [c[1] for c in base.commands]
    assert base.data["initial"]["beta_deg"] == 5.0          # the base is not modified


def test_uncoordinated_configurations_are_flown_once_per_observer_input():
    cfgs = C.configurations(limits=(3.0,))
    unco = [c for c in cfgs if not c.coordinated]
    assert len(unco) == 2 * len(C.SIGNS)                     # DOB achieved / M_c, per sign
    assert len({c.label() for c in cfgs}) == len(cfgs)
