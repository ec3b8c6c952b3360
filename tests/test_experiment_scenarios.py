"""Whole-system scenario: the paper's row-spacing experiment on reduced settings, end to end.

Runs the real command a researcher runs (`reproduce row-spacing`, each attempt a
full GPS-navigation bringup: simulator, localisation, move_base, navigator,
recorder) on two spacings and short rows, then generates the results page from
what it wrote. Reduced so that CI stays short: 6 plants per row, 1.0 m (the
canopies leave 0.30 m, narrower than the 0.67 m robot) and 1.8 m (the paper's
spacing), paced at real time so a busy 2-core machine cannot starve the
controllers.
"""
import json
import subprocess

REPRODUCE = ["rosrun", "cottonsim_experiments", "reproduce"]


def test_row_spacing_study_reduced(tmp_path):
    results = tmp_path / "results"
    cmd = [*REPRODUCE, "row-spacing", "--spacings", "1.0", "1.8", "--plants-per-row", "6",
           "--goal-timeout", "60", "--real-time-factor", "1", "--results", str(results)]
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:]
    summary = json.loads((results / "row_spacing" / "seed_0" / "summary.json").read_text())
    by_spacing = {round(a["spacing_m"], 2): a for a in summary["attempts"]}
    narrow, paper = by_spacing[1.0], by_spacing[1.8]
    runs = results / "row_spacing" / "runs"          # one folder per attempt, run by the sweep engine
    logs = {s: (runs / f"seed_0__row_spacing_m={s:g}" / "launch.log") for s in (1.0, 1.8)}
    assert all(log.is_file() for log in logs.values()), sorted(p.name for p in runs.iterdir())
    assert paper["traversed"], f"1.8 m not traversed: {paper['reason']}\n" + logs[1.8].read_text()[-3000:]
    assert paper["reached"] == 3 and paper["plant_contacts"] == 0
    assert not narrow["traversed"] and narrow["reason"], narrow
    assert summary["smallest_traversable_spacing_m"] == 1.8

    doc = tmp_path / "results.md"
    proc = subprocess.run([*REPRODUCE, "results-doc", "--results", str(results), "--doc", str(doc)],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout
    text = doc.read_text()
    assert "| 1.00 | 0.30 | no |" in text and "| 1.80 | 1.10 | yes | 3/3 | 0 |" in text
    assert "**1.80 m** (one seed)" in text
