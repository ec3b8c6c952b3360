"""Navigation's config dataclasses filled from ROS parameters (cottonsim_common.ros.params, no master)."""
import pytest

from cottonsim_common.ros.params import config_from_params, dict_parameter_server
from cottonsim_navigation.geodesy.navsat import NavsatConfig
from cottonsim_navigation.power.battery import BatteryConfig


def test_real_configs_from_yaml_like_values():
    get, has = dict_parameter_server({"~frequency": 10, "~delay": 0, "~zero_altitude": False, "~datum": [49.9, 8.9, 0.1]})
    cfg = config_from_params(NavsatConfig, get_param=get, has_param=has)
    assert (cfg.frequency, cfg.delay, cfg.zero_altitude, cfg.datum) == (10.0, 0.0, False, (49.9, 8.9, 0.1))
    get, has = dict_parameter_server({"~initial_percentage": 1.5})
    with pytest.raises(ValueError, match="~initial_percentage"):
        config_from_params(BatteryConfig, get_param=get, has_param=has)
    get, has = dict_parameter_server({"~frequency": 0.0})
    with pytest.raises(ValueError, match="~frequency"):
        config_from_params(NavsatConfig, get_param=get, has_param=has)
