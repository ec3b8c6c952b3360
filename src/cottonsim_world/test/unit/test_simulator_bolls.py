"""The Simulator and its bolls: a boll state change reaches the next camera and LiDAR readings, serial and
pipelined alike, and the same actions give the same readings."""
import pathlib

import numpy as np
import pytest

from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.farm.bolls import BollState
from cottonsim_world.farm.model import SemanticClass
from cottonsim_world.robot.urdf_model import UrdfModel
from cottonsim_world.readings import CameraReading, LidarReading
from cottonsim_world.simulator import Simulator

URDF = pathlib.Path(__file__).resolve().parents[3] / "cottonsim_description" / "urdf" / "cottonsim_robot.urdf"
CHANGE_S = 0.5


def config(workers):
    return simulator_config_from_dict({
        "seed": 1, "sensor_workers": workers,
        "farm": {"rows": 2, "plants_per_row": 4, "plant_detail": "low"},
        "cameras": {"realsense_p": {"enabled": False},
                    "realsense_secondary": {"width": 96, "height": 72, "rate_hz": 10.0},
                    "realsense_tertiary": {"enabled": False}},
        "lidar": {"samples_per_ring": 360, "noise_std_m": 0.0},
    })


@pytest.fixture(scope="module")
def urdf():
    return UrdfModel.from_file(URDF)


def run_and_pick(sim):
    """Stand in lane 1 beside the plants; at CHANGE_S every boll of the farm goes to the bin."""
    lane = sim.farm.lanes[1]
    sim.teleport_robot(lane.x_m, 0.5 * (lane.y_start_m + lane.y_end_m), np.pi / 2)
    readings = []
    while sim.time_s < 1.0 - 1e-9:
        if abs(sim.time_s - CHANGE_S) < 0.5 * sim.step_s:
            for i in range(sim.bolls.count):
                sim.bolls.drop_in_bin(i)
        readings.extend(sim.step())
    readings.extend(sim.flush_readings())
    sim.close()
    return readings


def boll_counts(readings):
    """(stamp, BOLL pixels or returns) per camera and LiDAR reading."""
    out = []
    for r in readings:
        if isinstance(r, CameraReading):
            out.append(("camera", r.stamp_s, int(np.count_nonzero(r.frame.semantic == SemanticClass.BOLL))))
        elif isinstance(r, LidarReading):
            out.append(("lidar", r.stamp_s, int(np.count_nonzero(r.scan.semantic == SemanticClass.BOLL))))
    return out


def test_bolls_in_the_bin_vanish_from_the_next_readings_serial_and_pipelined(urdf):
    serial, pipelined = Simulator(config(0), urdf), Simulator(config(1), urdf)
    serial_readings = run_and_pick(serial)
    counts = boll_counts(serial_readings)
    assert np.all(serial.bolls.states() == BollState.IN_BIN)
    for kind in ("camera", "lidar"):
        # the reading stamped CHANGE_S came out of the step that ended there, before the change
        before = [n for k, t, n in counts if k == kind and t < CHANGE_S + 1e-9]
        after = [n for k, t, n in counts if k == kind and t > CHANGE_S + 1e-9]
        assert before and after
        assert min(before) > 0, f"{kind} saw no boll before the harvest"
        assert max(after) == 0, f"{kind} still saw bolls after the harvest"
    # the worker thread's readings are the serial ones, bolls included
    pipelined_readings = run_and_pick(pipelined)
    assert boll_counts(pipelined_readings) == counts
    cams = lambda rs: [r.frame.rgb for r in rs if isinstance(r, CameraReading)]
    assert all(np.array_equal(a, b) for a, b in zip(cams(serial_readings), cams(pipelined_readings)))
