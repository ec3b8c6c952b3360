"""A local Ray cluster of 2 CPUs shared by the tests that run sweeps (the engine's and the reproduce experiments')."""
import os

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))


@pytest.fixture(scope="session")
def ray_cluster(tmp_path_factory):
    """Ray started once with 2 CPUs; the workers import this folder's stub modules (sweep_stub_runs)."""
    ray = pytest.importorskip("ray", reason="ray is a pinned requirement (requirements.txt); run scripts/setup.sh")
    markers = tmp_path_factory.mktemp("markers")
    os.environ["COTTONSIM_SWEEP_STUB_MARKERS"] = str(markers)
    os.environ["PYTHONPATH"] = HERE + os.pathsep + os.environ.get("PYTHONPATH", "")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    import sweep_stub_runs  # noqa: F401  (the same module the workers import)
    yield markers
    ray.shutdown()
