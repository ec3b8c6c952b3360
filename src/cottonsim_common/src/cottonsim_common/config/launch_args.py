"""Strict checking of the YAML files a launch file hands to a node.

Why: roslaunch loads ``<rosparam file=...>`` with PyYAML, which keeps the
last of two equal keys silently. A launch file that loads a user's file
(``config:=FILE``) also names it in the node's arguments as
``--config-file=FILE``; the node's executable calls
:func:`check_config_file_args` before it starts, which re-reads each such
file strictly and stops the node with one line naming the key and both
lines. The node is ``required`` in our launch files, so the whole bringup
stops with that line instead of running with a setting the user did not
mean.
"""
from __future__ import annotations

import os
import sys
from typing import List, Optional

from cottonsim_common.config.yaml_files import load_yaml_file

FLAG = "--config-file="


def pop_config_file_args(argv: List[str]) -> List[str]:
    """Remove every ``--config-file=PATH`` from ``argv`` (in place); return the non-empty paths in order."""
    paths = [arg[len(FLAG):] for arg in argv if arg.startswith(FLAG)]
    argv[:] = [arg for arg in argv if not arg.startswith(FLAG)]
    return [path for path in paths if path]


def check_config_file_args(argv: Optional[List[str]] = None) -> None:
    """Strictly read each ``--config-file=PATH`` of ``argv`` (default ``sys.argv``, which loses them).

    Exits with status 2 and one line on stderr when a file cannot be read,
    is not YAML or repeats a key.
    """
    argv = sys.argv if argv is None else argv
    program = os.path.basename(argv[0]) if argv else "node"
    for path in pop_config_file_args(argv):
        try:
            load_yaml_file(path)
        except ValueError as exc:
            print(f"{program}: refusing the configuration: {exc}", file=sys.stderr)
            raise SystemExit(2) from None
