"""Start a node the same way everywhere: init, build, fail clearly on a bad start, run.

Every executable under ``nodes/`` is a few lines that call :func:`run_node`
with the node's name and class. A start error (a bad parameter, a missing
file: the exceptions in ``start_errors``) becomes one ``rospy.logfatal`` line
naming the node and a non-zero exit, never a traceback.
"""
from __future__ import annotations

from typing import Callable, Optional, Sequence, Tuple, Type

import rospy

START_ERROR_EXIT_CODE = 2


def run_node(name: str, node_class: Type, start_errors: Tuple[Type[BaseException], ...] = (ValueError,),
             run: Optional[Callable[[object], Optional[int]]] = None, with_argv: bool = False,
             start_error_exit_code: int = START_ERROR_EXIT_CODE) -> None:
    """``rospy.init_node(name)``, build ``node_class()``, then run it; exits the process when it ends.

    with_argv: pass ``rospy.myargv()`` (the command line without ROS remappings) to the class.
    run: what to do with the built node (e.g. ``lambda node: node.spin()``); its integer result is
    the exit status. Default: ``rospy.spin()`` until shutdown.
    """
    rospy.init_node(name)
    args: Sequence = (rospy.myargv(),) if with_argv else ()
    try:
        node = node_class(*args)
    except start_errors as exc:
        rospy.logfatal(f"{name}: {exc}")
        raise SystemExit(start_error_exit_code)
    if run is None:
        rospy.spin()
        return
    code = run(node)
    if code is not None:
        raise SystemExit(code)
