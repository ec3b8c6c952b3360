"""Where reproduce finds packages and puts results: rospkg, --results, $COTTONSIM_RESULTS, never the source tree."""
import os

import pytest

from cottonsim_experiments.reproduce.cli import main
from cottonsim_experiments.reproduce.packages import (RESULTS_ENV, default_results_dir, package_file, package_path,
                                                      rosrun_command)
from cottonsim_experiments.reproduce.runs import Workspace


def test_results_default_to_the_environment_then_the_current_directory(tmp_path, monkeypatch):
    assert default_results_dir({RESULTS_ENV: str(tmp_path / "mine")}) == str(tmp_path / "mine")
    monkeypatch.chdir(tmp_path)
    assert default_results_dir({}) == str(tmp_path / "results")
    assert default_results_dir({RESULTS_ENV: ""}) == str(tmp_path / "results")


def test_packages_are_found_by_name_and_a_missing_one_is_named():
    nav = package_path("cottonsim_navigation")
    assert os.path.isfile(os.path.join(nav, "package.xml"))
    assert package_file("cottonsim_navigation", "config/boll_halt.yaml").startswith(nav)
    with pytest.raises(ValueError, match="cottonsim_no_such_package"):
        package_path("cottonsim_no_such_package")
    with pytest.raises(ValueError, match="no_such_file.yaml"):
        package_file("cottonsim_navigation", "config/no_such_file.yaml")
    assert rosrun_command("p", "x", ["--a", "1"]) == ["rosrun", "p", "x", "--a", "1"]


def test_workspace_finds_the_packages_and_needs_a_results_folder(tmp_path):
    ws = Workspace(results=str(tmp_path / "r"))
    assert ws.navigation == package_path("cottonsim_navigation")
    assert ws.perception == package_path("cottonsim_perception")
    assert Workspace(results="rel", navigation="/n", perception="/p").results == os.path.abspath("rel")
    with pytest.raises(ValueError, match="results"):
        Workspace(results="")


def test_results_page_goes_under_the_results_folder_by_default(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(RESULTS_ENV, str(tmp_path / "from_env"))
    assert main(["results-doc"]) == 0
    assert (tmp_path / "from_env" / "results.md").is_file()
    assert main(["results-doc", "--results", str(tmp_path / "given"), "--doc", str(tmp_path / "page.md")]) == 0
    text = (tmp_path / "page.md").read_text()
    assert "rosrun cottonsim_experiments reproduce gps-route" in text
    assert "No results yet" in text
    assert not (tmp_path / "given" / "results.md").exists()
    capsys.readouterr()


def test_a_bad_request_exits_2_with_one_line(tmp_path, capsys):
    assert main(["perception", "--results", str(tmp_path), "--original-data", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("reproduce: ") and "nowhere" in err
