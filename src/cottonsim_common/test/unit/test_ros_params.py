"""config_from_params / typed_param with an injected parameter dictionary (no ROS master)."""
from dataclasses import dataclass
from typing import Optional, Tuple

import pytest

from cottonsim_common.ros.params import config_from_params, dict_parameter_server, typed_param


@dataclass(frozen=True)
class Sample:
    rate_hz: float = 2.0
    count: int = 3
    enabled: bool = False
    name: str = "a"
    pair: Tuple[float, float] = (0.0, 1.0)
    many: Tuple[float, ...] = ()
    maybe: Optional[Tuple[float, float, float]] = None

    def __post_init__(self):
        if self.rate_hz <= 0:
            raise ValueError(f"rate_hz must be > 0, got {self.rate_hz}")


def test_unset_parameters_keep_the_defaults():
    get, has = dict_parameter_server({})
    assert config_from_params(Sample, get_param=get, has_param=has) == Sample()


def test_values_are_converted_to_the_field_types():
    get, has = dict_parameter_server({"~rate_hz": 5, "~count": 7.0, "~enabled": "true", "~name": "b",
                       "~pair": [1, 2], "~many": [1, 2.5, 3], "~maybe": [49.9, 8.9, 0]})
    cfg = config_from_params(Sample, get_param=get, has_param=has)
    assert cfg.rate_hz == 5.0 and isinstance(cfg.rate_hz, float)
    assert cfg.count == 7 and isinstance(cfg.count, int)
    assert cfg.enabled is True and cfg.name == "b"
    assert cfg.pair == (1.0, 2.0) and cfg.many == (1.0, 2.5, 3.0) and cfg.maybe == (49.9, 8.9, 0.0)


def test_prefix_and_overrides():
    get, has = dict_parameter_server({"/ns/rate_hz": 4.0, "/ns/count": 9})
    cfg = config_from_params(Sample, prefix="/ns/", overrides={"count": 1}, get_param=get, has_param=has)
    assert cfg.rate_hz == 4.0 and cfg.count == 1


@pytest.mark.parametrize("values, named", [
    ({"~rate_hz": "fast"}, "~rate_hz"),
    ({"~rate_hz": True}, "~rate_hz"),
    ({"~count": 2.5}, "~count"),
    ({"~enabled": 3}, "~enabled"),
    ({"~pair": [1.0]}, "~pair"),
    ({"~pair": 1.0}, "~pair"),
    ({"~many": [1.0, "x"]}, r"~many\[1\]"),
    ({"~rate_hz": -1.0}, "~rate_hz"),            # refused by the dataclass itself
    ({"~rate_hz": float("nan")}, "~rate_hz"),
])
def test_bad_values_name_the_parameter(values, named):
    get, has = dict_parameter_server(values)
    with pytest.raises(ValueError, match=named):
        config_from_params(Sample, get_param=get, has_param=has)


def test_not_a_dataclass_is_refused():
    get, has = dict_parameter_server({})
    with pytest.raises(ValueError, match="dataclass"):
        config_from_params(dict, get_param=get, has_param=has)


def test_typed_param():
    get, _ = dict_parameter_server({"~rate": 3, "~frame": "map", "~flag": "false", "~origin": [1, 2, 0], "~bad": "x"})
    assert typed_param("~rate", 1.0, get_param=get) == 3.0
    assert typed_param("~missing", 1.5, get_param=get) == 1.5
    assert typed_param("~frame", "odom", get_param=get) == "map"
    assert typed_param("~flag", True, get_param=get) is False
    assert typed_param("~origin", (0.0, 0.0, 0.0), get_param=get) == (1.0, 2.0, 0.0)
    with pytest.raises(ValueError, match="~bad"):
        typed_param("~bad", 1.0, get_param=get)
    with pytest.raises(ValueError, match="~rate: must be >= 5"):
        typed_param("~rate", 1.0, get_param=get, minimum=5)
