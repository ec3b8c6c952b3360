"""cottonsim_common.validation: each check returns the clean value or names the key in its error."""
import math

import numpy as np
import pytest

from cottonsim_common.validation import (is_number, require_bool, require_fields, require_finite, require_finite_array,
                                         require_finite_values, require_instance, require_int, require_min_max,
                                         require_number, require_positive)


def test_numbers_and_bounds():
    assert is_number(np.float32(1.5)) and not is_number(True) and not is_number("1")
    assert require_number("gain", 2, 0.0, 5.0) == 2.0
    with pytest.raises(ValueError, match=r"gain must be in \[0, 5\], got 6"):
        require_number("gain", 6, 0.0, 5.0)
    with pytest.raises(ValueError, match="gain must be a number"):
        require_number("gain", "2")
    assert require_positive("rate_hz", 3) == 3.0
    assert require_positive("margin_m", 0, allow_zero=True) == 0.0
    for bad in (0, -1, math.inf, math.nan):
        with pytest.raises(ValueError, match="rate_hz must be a finite number > 0"):
            require_positive("rate_hz", bad)
    with pytest.raises(ValueError, match="offset must be finite"):
        require_finite("offset", -math.inf)


def test_integers_pairs_and_arrays():
    assert require_int("workers", np.int64(3), 1) == 3
    for bad in (0, 2.0, True):
        with pytest.raises(ValueError, match="workers must be an integer >= 1"):
            require_int("workers", bad, 1)
    with pytest.raises(ValueError, match=r"beams must be an integer in \[1, 4\]"):
        require_int("beams", 5, 1, 4)
    assert require_min_max("height_m", [0.2, 0.5], 0.0) == (0.2, 0.5)
    with pytest.raises(ValueError, match="height_m must satisfy"):
        require_min_max("height_m", (0.5, 0.2))
    assert require_finite_values("origin", [1, 2, 0], 3) == (1.0, 2.0, 0.0)
    with pytest.raises(ValueError, match=r"origin\[1\] must be finite"):
        require_finite_values("origin", [1, math.nan, 0], 3)
    with pytest.raises(ValueError, match="origin must be 3 numbers"):
        require_finite_values("origin", [1, 2], 3)
    with pytest.raises(ValueError, match=r"covariance must be 2 finite numbers >= 0, got \(0.1, -0.1\)"):
        require_finite_values("covariance", (0.1, -0.1), 2, low=0.0)
    assert require_finite_array("points", [[1, 2]], (None, 2)).shape == (1, 2)
    with pytest.raises(ValueError, match=r"points must have shape \(N, 2\)"):
        require_finite_array("points", [1, 2, 3], (None, 2))
    with pytest.raises(ValueError, match="points contains NaN"):
        require_finite_array("points", [math.nan])


def test_require_instance_returns_the_value_or_names_both_types():
    config = {"a": 1}
    assert require_instance("config", config, dict) is config
    with pytest.raises(ValueError, match=r"^config must be a dict, got list$"):
        require_instance("config", [], dict)
    with pytest.raises(ValueError, match=r"^amcl must be an int, got str$"):
        require_instance("amcl", "x", int)


def test_assert_config_rejects_fails_for_an_accepted_value_or_an_error_that_does_not_name_the_key():
    from dataclasses import dataclass

    from cottonsim_common.testing import assert_config_rejects

    @dataclass
    class Config:
        rate_hz: float = 1.0
        name: str = "a"

        def __post_init__(self):
            require_positive("rate_hz", self.rate_hz)
            if self.name not in ("a", "b"):
                raise ValueError("bad value")          # does not name the key

    assert_config_rejects(Config, ("rate_hz", 0.0), ("rate_hz", -1.0, r"rate_hz must be a finite number > 0"))
    with pytest.raises(AssertionError, match=r"Config\(rate_hz=2.0\) was accepted"):
        assert_config_rejects(Config, ("rate_hz", 2.0))
    with pytest.raises(AssertionError, match="does not name 'name'"):
        assert_config_rejects(Config, ("name", "c"))
    with pytest.raises(AssertionError, match="does not name 'rate_hz'"):
        assert_config_rejects(Config, ("rate_hz", 0.0, "no such text"))


def test_require_unit_vector_scales_to_length_one_and_names_a_zero_or_bad_vector():
    from cottonsim_common.validation import require_unit_vector

    np.testing.assert_allclose(require_unit_vector("axis", [0.0, 3.0, 4.0], 3), [0.0, 0.6, 0.8])
    with pytest.raises(ValueError, match=r"axis must be 3 finite numbers"):
        require_unit_vector("axis", [0.0, math.inf, 1.0], 3)
    with pytest.raises(ValueError, match=r"q must be 4 finite numbers"):
        require_unit_vector("q", [0.0, 0.0, 1.0], 4)
    with pytest.raises(ValueError, match="q must not be the zero quaternion"):
        require_unit_vector("q", [0.0] * 4, 4, "the zero quaternion")


def test_flags_are_true_or_false_only():
    assert require_bool("enabled", False) is False
    for bad in (0, 1, "true", None):
        with pytest.raises(ValueError, match="enabled must be true or false"):
            require_bool("enabled", bad)


def test_require_fields_checks_each_named_field_by_its_rule():
    class Config:
        enabled, rate_hz, margin_m, share, workers, offset_m = True, 10.0, 0.0, 0.5, 2, -1.5

    good = Config()
    require_fields(good, flags=("enabled",), positive=("rate_hz",), non_negative=("margin_m",), fractions=("share",),
                   counts=("workers",), finite=("offset_m",))
    cases = [("enabled", 1, "must be true or false", "flags"), ("offset_m", math.inf, "must be finite", "finite"),
             ("rate_hz", 0.0, "must be a finite number > 0", "positive"),
             ("margin_m", -1.0, "must be a finite number >= 0", "non_negative"),
             ("share", 1.5, r"must be in \[0, 1\]", "fractions"), ("workers", 0, "must be an integer >= 1", "counts")]
    for field, bad, message, rule in cases:
        config = Config()
        setattr(config, field, bad)
        with pytest.raises(ValueError, match=f"Config.{field} {message}"):
            require_fields(config, "Config.", **{rule: (field,)})
    with pytest.raises(TypeError, match="unknown rule"):
        require_fields(good, finites=("rate_hz",))
    with pytest.raises(TypeError, match="not the string"):
        require_fields(good, positive="rate_hz")
