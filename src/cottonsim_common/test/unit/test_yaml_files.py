"""Strict YAML: repeated keys are refused with both lines named."""
import pytest

from cottonsim_common.config.yaml_files import DuplicateKeyError, YamlSyntaxError, load_yaml_file, load_yaml_text


def test_a_repeated_top_level_key_names_the_key_and_both_lines():
    with pytest.raises(DuplicateKeyError, match=r"'real_time_factor' is given twice, on lines 1 and 3") as err:
        load_yaml_text("real_time_factor: 1.0\nseed: 0\nreal_time_factor: 0.0\n", source="sim.yaml")
    assert (err.value.first_line, err.value.second_line) == (1, 3)
    assert str(err.value).startswith("sim.yaml:")


def test_a_repeated_nested_key_is_refused_but_equal_keys_in_sibling_mappings_are_fine():
    text = "lidar:\n  rate_hz: 10\n  noise_m: 0.01\n  rate_hz: 5\ncamera:\n  rate_hz: 30\n"
    with pytest.raises(DuplicateKeyError, match=r"'rate_hz'.*lines 2 and 4"):
        load_yaml_text(text)
    assert load_yaml_text("a: {rate_hz: 1}\nb: {rate_hz: 2}\n") == {"a": {"rate_hz": 1}, "b": {"rate_hz": 2}}


def test_keys_equal_after_construction_are_repeats():
    # 1 and 1.0 are the same key once loaded, so YAML would keep one of them
    with pytest.raises(DuplicateKeyError):
        load_yaml_text("1: a\n1.0: b\n")


def test_plain_documents_load_as_pyyaml_loads_them():
    text = "a: 1\nb: [1, 2, {c: x}]\nbase: &b {p: 1}\nderived:\n  <<: *b\n  q: 2\n"
    assert load_yaml_text(text) == {"a": 1, "b": [1, 2, {"c": "x"}], "base": {"p": 1}, "derived": {"p": 1, "q": 2}}
    assert load_yaml_text("") is None


def test_files_empty_missing_and_invalid(tmp_path):
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing set\n")
    assert load_yaml_file(empty, default={}) == {}
    with pytest.raises(ValueError, match="cannot read YAML file .*missing.yaml"):
        load_yaml_file(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: [1, 2\n")
    with pytest.raises(YamlSyntaxError, match=r"bad.yaml: not valid YAML \(line 2\)") as err:
        load_yaml_file(bad)
    assert err.value.line == 2
    unsafe = tmp_path / "unsafe.yaml"
    unsafe.write_text("a: !!python/object/apply:os.system ['true']\n")
    with pytest.raises(ValueError, match="unsafe.yaml: not valid YAML"):
        load_yaml_file(unsafe)

