#!/usr/bin/env python3
"""CPU cost of the odometry EKF's 50 Hz cycle (update_imu + predict + update_wheel_odometry), with and without
the IMU wheel-slip check (cottonsim_world/estimation/odometry_ekf.py). Best of 5 x 5000 cycles, in us.

Run:  source scripts/env.sh && python benchmarks/bench_odometry_ekf.py
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src/cottonsim_world/src"))

from cottonsim_world.estimation.odometry_ekf import OdometryEkf, OdometryEkfConfig  # noqa: E402


def main():
    acc = np.array([0.01, 0.0, 9.8])            # as the simulator passes them: numpy arrays
    q = np.array([0.0, 0.0, 0.1, 0.995])
    for check in (False, True):
        ekf = OdometryEkf(OdometryEkfConfig(slip_check=check))
        best = float("inf")
        for _ in range(5):
            t = time.process_time()
            for _ in range(5000):
                ekf.update_imu(0.1, 1e-4, accel_body_m_s2=acc, orientation_xyzw=q)
                ekf.predict(0.02)
                ekf.update_wheel_odometry(0.5, 0.1, (1e-3, 1e-3))
            best = min(best, (time.process_time() - t) / 5000 * 1e6)
        print(f"EKF cycle, slip check {'on ' if check else 'off'}: {best:5.1f} us CPU")


if __name__ == "__main__":
    main()
