"""Which host name ROS nodes advertise, on machines whose own host name does not resolve.

Why: rospy builds each node's address from ``ROS_HOSTNAME``, ``ROS_IP`` or,
when neither is set, the machine's host name. On cloud VMs, containers and
chroots that name is often missing from /etc/hosts and DNS, and every node
then dies with ``socket.gaierror: Name or service not known``, which says
nothing of the cause. Our bringups and tests run a master of their own on
this machine, so the loopback is the right address when the user has set
none: :func:`ros_network_environment` returns the environment to start them
with, and refuses a ``ROS_HOSTNAME`` that does not resolve with one line
saying what to fix. No ROS import: this only looks at names.
"""
from __future__ import annotations

import socket
from typing import Callable, Mapping, Optional, Tuple

LOOPBACK_HOSTNAME = "localhost"


def name_resolves(name: str, resolver: Callable = socket.getaddrinfo) -> bool:
    """True when ``name`` resolves to an address (``resolver`` as socket.getaddrinfo)."""
    try:
        return bool(resolver(name, None))
    except (OSError, UnicodeError):
        return False


def ros_network_environment(environ: Mapping[str, str], hostname: Optional[str] = None,
                            resolver: Callable = socket.getaddrinfo) -> Tuple[dict, Optional[str]]:
    """(environment for ROS processes, a note to print or None).

    * ``ROS_IP`` set: kept as it is (an address needs no lookup).
    * ``ROS_HOSTNAME`` set: kept when it resolves; otherwise ``ValueError``
      naming it and the fix.
    * neither set and the host name resolves: unchanged.
    * neither set and the host name does not resolve: ``ROS_HOSTNAME=localhost``
      and a note saying so.
    """
    env = dict(environ)
    if env.get("ROS_IP"):
        return env, None
    if env.get("ROS_HOSTNAME"):
        if not name_resolves(env["ROS_HOSTNAME"], resolver):
            raise ValueError(f"ROS_HOSTNAME={env['ROS_HOSTNAME']} does not resolve: add it to /etc/hosts, or "
                             f"export ROS_HOSTNAME=localhost to keep ROS on this machine")
        return env, None
    hostname = socket.gethostname() if hostname is None else hostname
    if name_resolves(hostname, resolver):
        return env, None
    env["ROS_HOSTNAME"] = LOOPBACK_HOSTNAME
    return env, (f"this machine's host name {hostname!r} does not resolve (not in /etc/hosts or DNS), so ROS "
                 f"nodes advertise ROS_HOSTNAME={LOOPBACK_HOSTNAME}; set ROS_HOSTNAME or ROS_IP to reach other "
                 f"machines")
