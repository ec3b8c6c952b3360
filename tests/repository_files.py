"""The repository's own files, for the house-rule tests that read every file of a kind.

In a git checkout these are the files git tracks; in a copy without ``.git``
(the Docker image) every file below the root except the build outputs. A
pathspec is a folder (``src``: every file below it) or a glob on the path from
the root (``*.yaml``: in any folder), as ``git ls-files`` reads it.
"""
import fnmatch
import pathlib
import subprocess

ROOT = pathlib.Path(__file__).resolve().parents[1]
BUILD_OUTPUTS = {".git", "build", "devel", "install", ".venv", "logs", "results", "__pycache__"}


def _matches(name: str, pathspec: str) -> bool:
    if any(c in pathspec for c in "*?["):
        return fnmatch.fnmatchcase(name, pathspec)
    return name == pathspec or name.startswith(pathspec.rstrip("/") + "/")


def repository_files(*pathspecs: str) -> list:
    """Paths relative to ROOT (sorted) of the repository's files that match any of ``pathspecs``."""
    listing = subprocess.run(["git", "ls-files", *pathspecs], cwd=ROOT, capture_output=True, text=True)
    if listing.returncode == 0 and (ROOT / ".git").exists():
        return sorted(listing.stdout.split())
    names = (str(p.relative_to(ROOT)) for p in ROOT.rglob("*")
             if p.is_file() and not BUILD_OUTPUTS & set(p.relative_to(ROOT).parts))
    return sorted(name for name in names if any(_matches(name, spec) for spec in pathspecs))
