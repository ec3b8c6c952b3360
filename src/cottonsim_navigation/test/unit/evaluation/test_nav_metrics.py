import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from cottonsim_navigation.evaluation.metrics import (cross_track_errors, report_dict, route_metrics,
                                                     waypoint_errors)


def test_errors_and_metrics_hand_computed():
    planned = [[0, 0], [1, 0], [2, 0]]
    actual = [[0, 0.1], [1, 0.3], [2.4, 0.0], [5, 5]]
    e = waypoint_errors(planned, actual)
    assert e.tolist() == pytest.approx([0.1, 0.3, 0.4])
    m = route_metrics(e, 0.25)
    assert m.ae == pytest.approx(0.8 / 3)
    assert m.rmse == pytest.approx(math.sqrt((0.01 + 0.09 + 0.16) / 3))
    assert m.cr_percent == pytest.approx(100 / 3) and m.reached == 1


def test_cross_track_only_inside_rows():
    traj = [[0.1, 5.0], [-1.9, 6.0], [0.0, 50.0], [0.3, 9.0]]
    ct = cross_track_errors(traj, [0.0, -1.8], [0.0, 0.0], [10.0, 10.0])
    assert sorted(ct.tolist()) == pytest.approx([0.1, 0.1, 0.3])


def test_report_keys(tmp_path):
    lanes = [SimpleNamespace(x_m=0.0, y_start_m=0.0, y_end_m=10.0)]
    r = report_dict("map", [[0, 0], [0, 10]], np.column_stack([np.full(11, 0.05), np.arange(11.0)]),
                    sim_duration_s=100.0, wall_duration_s=50.0, plant_contacts=2, lanes=lanes)
    assert set(r) == {"mode", "waypoints", "reached", "ae_m", "rmse_m", "cr_percent", "cr_threshold",
                      "cr_percent_010m", "sim_duration_s", "wall_duration_s", "real_time_factor",
                      "plant_contacts", "cross_track_mean_m", "cross_track_max_m"}
    assert r["ae_m"] == pytest.approx(0.05) and r["real_time_factor"] == 2.0 and r["cr_percent"] == 100.0
    assert r["cross_track_max_m"] == pytest.approx(0.05)
    json.dumps(r)
    g = report_dict("gps", [[49.9, 8.9]], [[49.9 + 4e-6, 8.9]], 1.0, 1.0)
    assert g["cr_percent"] == 100.0 and g["cr_threshold"] == 5e-6 and g["ae_m"] is None
    with pytest.raises(ValueError, match="mode"):
        report_dict("x", [[0, 0]], [[0, 0]], 1, 1)


def test_plot_writes_png(tmp_path):
    from cottonsim_navigation.evaluation.plots import plot_trajectory
    out = plot_trajectory(tmp_path / "f.png", [[0, 0], [1, 1]], [[0, 0], [0.5, 0.6], [1, 1]], [[0.5, 0.0]])
    data = open(out, "rb").read(8)
    assert data.startswith(b"\x89PNG")
