"""The ODE library as loaded: pyode's module and the constants of the libode under it.

pyode's constants predate ODE 0.16 (Debian's libode8): its ``ode.ParamFMax``
and ``ode.ContactSlip1`` silently set other parameters on libode 0.16. The
joint parameter indices and contact mode flags here are those of the loaded
library (probed once at import, ``_motor_param_indices``), and the collision
category bits of the three kinds of geoms the world holds.
"""
from __future__ import annotations

from typing import Tuple

try:
    import ode  # Debian: python3-pyode
except ImportError as exc:  # pragma: no cover - depends on the machine
    raise ImportError("cottonsim_world.physics needs python3-pyode for the ODE world "
                      "(apt-get install python3-pyode)") from exc


def _motor_param_indices() -> Tuple[int, int]:
    """(ParamVel, ParamFMax) indices of the libode actually loaded.

    pyode's constants predate ODE 0.16, which inserted dParamLoVel and
    dParamHiVel before dParamFMax (so pyode's ``ode.ParamFMax`` == 3 sets
    LoVel on Debian's libode 0.16 and the motor never gets a torque). A
    fresh joint has FudgeFactor == 1 and every other parameter != 1; where
    that 1 sits tells the layout.
    """
    probe = ode.HingeJoint(ode.World())
    values = [probe.getParam(i) for i in range(8)]
    if values[6] == 1.0:          # Lo, Hi, Vel, LoVel, HiVel, FMax, Fudge
        return 2, 5
    if values[4] == 1.0:          # Lo, Hi, Vel, FMax, Fudge (ODE < 0.16)
        return 2, 3
    raise RuntimeError(f"unknown ODE joint parameter layout {values}; cannot drive the wheel motors")


PARAM_VEL, PARAM_FMAX = _motor_param_indices()

# Contact mode flags. pyode's ode.ContactSlip1/2 and ode.ContactApprox1 are
# the pre-0.12 values; ODE 0.12+ inserted dContactMotionN (0x80), moving
# Slip1/Slip2 to 0x100/0x200 and adding Approx1_N (0x4000). With pyode's
# constants on libode 0.16 "Slip1" sets MotionN and "Slip2" sets Slip1,
# which makes friction anisotropic in world axes. The joint layout probe
# above tells the two library generations apart (LoVel/HiVel came in 0.16).
if PARAM_FMAX == 5:
    MODE_MU2, MODE_SOFT_ERP, MODE_SOFT_CFM = 0x001, 0x008, 0x010
    MODE_FDIR1, MODE_SLIP1, MODE_SLIP2, MODE_APPROX1 = 0x002, 0x100, 0x200, 0x7000
else:  # pragma: no cover - old libode
    MODE_MU2, MODE_SOFT_ERP, MODE_SOFT_CFM = ode.ContactMu2, ode.ContactSoftERP, ode.ContactSoftCFM
    MODE_FDIR1, MODE_SLIP1, MODE_SLIP2, MODE_APPROX1 = (ode.ContactFDir1, ode.ContactSlip1,
                                                        ode.ContactSlip2, ode.ContactApprox1)

# Category bits of the three kinds of geoms.
CAT_ROBOT = 0x1
CAT_GROUND = 0x2
CAT_PLANT = 0x4
