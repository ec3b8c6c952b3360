"""House rule: a user's clone is all there is.

Nothing in the product, its tests, benchmarks or scripts may read a folder
beside the repository (our machines keep reference data in ``../shared``) or
an absolute path of our machines: a user's clone has neither, so such a read
fails there, or worse, silently skips what it was meant to check. Data the
project needs is committed (the original routes under
``cottonsim_navigation/config/waypoints/``) or given by the user (the paper's
labelled images: ``--original-data`` / ``$COTTONSIM_PAPER_DATA``).
"""
import pathlib
import re

import pytest

from repository_files import ROOT, repository_files

OUTSIDE_PATH = re.compile(r"/work/|\.\./shared\b|\bshared/(?:reference|datasets|seed|tools)\b"
                          r"|\bparents?\b.*[\"']shared[\"']")
CHECKED_SUFFIXES = {".py", ".sh", ".launch", ".test", ".yaml", ".yml", ".xml", ".txt", ".cfg", ""}


CHECKED_FOLDERS = ("src", "tests", "scripts", "benchmarks", "docker", ".ci")


def tracked_text_files():
    for name in repository_files(*CHECKED_FOLDERS):
        path = ROOT / name
        if path.suffix in CHECKED_SUFFIXES and path.is_file() and path != pathlib.Path(__file__).resolve():
            yield path


def test_no_file_reads_outside_the_repository():
    offenders = []
    for path in tracked_text_files():
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            if OUTSIDE_PATH.search(line):
                offenders.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not offenders, "paths outside the repository:\n" + "\n".join(offenders)


@pytest.mark.parametrize("line", ['WAYPOINTS = "/work/shared/reference/original_gps_waypoints.txt"',
                                  'default=str(ROOT.parent / "shared" / "datasets")',
                                  "--data ../shared/datasets/cottonsim_original/Detection"])
def test_the_rule_catches_outside_paths(line):
    assert OUTSIDE_PATH.search(line)


def test_the_rule_passes_repository_paths():
    assert not OUTSIDE_PATH.search('WAYPOINT_DIR = pathlib.Path(__file__).parents[3] / "config" / "waypoints"')
