"""tools/blackout.py's table (docs/reliability.md tables A and B are its output, not retyped)."""
from tools.blackout import TABLE_HEAD, markdown_table


def _run(**kw):
    r = {"sim_time_cut_s": 9.871, "modes": [4, 3, 4], "mu_abs_max_deg": 119.06,
         "alpha_range_deg": [1.44, 5.66], "surface_on_limit_longest_s": 0.172,
         "alt_from_target_before_cut_m": {"max": 1732.2, "end": -978.4}, "failsafe_frames": 80,
         "recovery_s": None, "ok": False}
    r.update(kw)
    return r


def test_one_row_per_run_in_the_documented_columns():
    text = markdown_table([_run(blackout_wall_s=10.0),
                           _run(run="/x/lockstep-link-0.5s", modes=[4], mu_abs_max_deg=0.1,
                                recovery_s=0.0, ok=True)])
    lines = text.splitlines()
    assert lines[:2] == TABLE_HEAD.splitlines()
    assert lines[2] == ("| 10 s | 9.87 | CRUISE FS CRUISE | 119.1 | 1.4..5.7 | 0.17 | "
                        "1732 / -978 | 80 | never | **no** |")
    assert lines[3].startswith("| 0.5 s | 9.87 | CRUISE | 0.1 |") and lines[3].endswith(
        "| 0.0 s | yes |")
