"""The whole-system launch files pick the navigation configs written for their route."""
import pathlib
import xml.etree.ElementTree as ET

import pytest

LAUNCH = pathlib.Path(__file__).resolve().parents[2] / "launch"


def _arg_defaults(launch_file: str) -> dict:
    root = ET.parse(LAUNCH / launch_file).getroot()
    return {a.get("name"): a.get("default") for a in root.iter("arg")}


@pytest.mark.parametrize("launch_file,move_base_config", [
    ("map_navigation.launch", "map_navigation_move_base.yaml"),
    ("gps_navigation.launch", "gps_navigation_move_base.yaml"),
])
def test_route_launch_uses_its_own_move_base_overrides(launch_file, move_base_config):
    default = _arg_defaults(launch_file)["move_base_config"]
    assert default == f"$(find cottonsim_navigation)/config/{move_base_config}"


@pytest.mark.parametrize("launch_file", ["gps_navigation.launch", "map_navigation.launch", "mapping.launch"])
def test_route_launch_reads_the_simulator_settings_of_this_package(launch_file):
    assert _arg_defaults(launch_file)["sim_config"] == "$(find cottonsim_experiments)/config/sim_navigation.yaml"
