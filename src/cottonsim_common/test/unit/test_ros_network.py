"""The host name ROS nodes advertise when the machine's own does not resolve."""
import socket

import pytest

from cottonsim_common.ros_network import name_resolves, ros_network_environment

KNOWN = {"localhost", "farm-pc"}


def resolver(name, port):
    if name not in KNOWN:
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")
    return [(socket.AF_INET, socket.SOCK_STREAM, 6, "", ("127.0.0.1", 0))]


def test_a_resolvable_host_name_changes_nothing():
    env, note = ros_network_environment({"PATH": "/bin"}, hostname="farm-pc", resolver=resolver)
    assert env == {"PATH": "/bin"} and note is None


def test_an_unresolvable_host_name_falls_back_to_the_loopback_with_a_note():
    env, note = ros_network_environment({"PATH": "/bin"}, hostname="ip-10-0-0-7", resolver=resolver)
    assert env["ROS_HOSTNAME"] == "localhost"
    assert "'ip-10-0-0-7' does not resolve" in note


def test_what_the_user_set_is_kept_or_refused_with_the_fix():
    env, note = ros_network_environment({"ROS_IP": "10.0.0.7"}, hostname="ip-10-0-0-7", resolver=resolver)
    assert env == {"ROS_IP": "10.0.0.7"} and note is None
    env, note = ros_network_environment({"ROS_HOSTNAME": "farm-pc"}, hostname="ip-10-0-0-7", resolver=resolver)
    assert env == {"ROS_HOSTNAME": "farm-pc"} and note is None
    with pytest.raises(ValueError, match="ROS_HOSTNAME=robot does not resolve.*export ROS_HOSTNAME=localhost"):
        ros_network_environment({"ROS_HOSTNAME": "robot"}, hostname="farm-pc", resolver=resolver)


def test_name_resolves_uses_the_system_resolver_by_default():
    assert name_resolves("localhost")
    assert not name_resolves("cottonsim-no-such-host.invalid")
