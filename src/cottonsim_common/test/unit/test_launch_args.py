"""--config-file=PATH arguments: taken out of argv, each file read strictly."""
import pytest

from cottonsim_common.config.launch_args import check_config_file_args, pop_config_file_args


def test_config_file_arguments_leave_argv_and_empty_ones_are_ignored():
    argv = ["move_base", "--config-file=a.yaml", "__name:=move_base", "--config-file=", "--config-file=b.yaml"]
    assert pop_config_file_args(argv) == ["a.yaml", "b.yaml"]
    assert argv == ["move_base", "__name:=move_base"]


def test_a_good_file_passes_and_a_repeated_key_stops_the_node_with_one_line(tmp_path, capsys):
    good = tmp_path / "good.yaml"
    good.write_text("planner_patience: 5.0\n")
    argv = ["move_base", f"--config-file={good}"]
    check_config_file_args(argv)
    assert argv == ["move_base"]
    bad = tmp_path / "bad.yaml"
    bad.write_text("planner_patience: 5.0\nDWAPlannerROS:\n  max_vel_x: 0.5\nplanner_patience: 1.0\n")
    with pytest.raises(SystemExit) as stop:
        check_config_file_args(["move_base", f"--config-file={bad}"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "move_base: refusing the configuration" in err and "'planner_patience' is given twice, on lines 1 and 4" in err
