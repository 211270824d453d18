"""HIL tier: the fc and the plant as two real processes (lockstep): the estimator's mu and gamma,
computed from the MAVLink messages, against the plant's truth over the paper's manoeuvre."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from tests.fc_harness import REPO, FcProcess

pytestmark = pytest.mark.hil

TIMELINE = "[[command]]\nt_s = 0.0\nalpha_deg = 5.0\nbeta_deg = 0.0\nmu_deg = 4.0\n"


def test_estimated_mu_gamma_from_messages_match_plant_truth(tmp_path):
    from fc.internals_log import load as load_fc
    from plant_sim.truthlog import load as load_truth

    fc_dir, plant_dir = str(tmp_path / "fc"), str(tmp_path / "plant")
    os.makedirs(fc_dir)
    with open(os.path.join(fc_dir, "params.parm"), "w") as f:
        f.write("FS_TIMEOUT_S 30\n")           # a loaded machine may pause the plant
    tl = tmp_path / "timeline.toml"
    tl.write_text(TIMELINE)
    with FcProcess(fc_dir, "--arm", "--flight-mode", "COORDINATED", "--timeline", str(tl)) as fc:
        res = subprocess.run(
            [sys.executable, "-m", "plant_sim", "run", "--scenario", "paper", "--mode", "lockstep",
             "--fc", f"127.0.0.1:{fc.plant_port}", "--bind", "127.0.0.1:0", "--out", plant_dir,
             "--duration", "4", "--seed", "2"],
            cwd=REPO, capture_output=True, text=True, timeout=180)
        assert res.returncode == 0, res.stderr
        assert fc.stop() == 0
    est = load_fc(fc_dir)
    truth = load_truth(plant_dir)
    # match rows by sensor time (the fc logs the frame's stamp; the truth row holds the state at it)
    t_truth = np.round(truth["t_s"] * 1e6).astype(np.int64)
    index = {t: i for i, t in enumerate(t_truth)}
    rows = [(index[t], j) for j, t in enumerate(est["stamp_us"].astype(np.int64)) if t in index]
    assert len(rows) > 1500
    ti, ei = np.array(rows).T
    mu_err = np.degrees(est["est_mu_rad"][ei] - truth["mu_rad"][ti])
    gamma_err = np.degrees(est["est_gamma_rad"][ei] - truth["gamma_rad"][ti])
    print(f"over {len(rows)} frames: mu error rms {np.sqrt(np.mean(mu_err**2)):.4f} deg "
          f"max {np.abs(mu_err).max():.4f}; gamma error rms {np.sqrt(np.mean(gamma_err**2)):.4f} "
          f"max {np.abs(gamma_err).max():.4f} deg")
    assert np.degrees(np.ptp(truth["mu_rad"])) > 2.0          # the vehicle did bank
    assert np.sqrt(np.mean(mu_err ** 2)) < 0.1 and np.abs(mu_err).max() < 0.5
    assert np.sqrt(np.mean(gamma_err ** 2)) < 0.1 and np.abs(gamma_err).max() < 0.5
