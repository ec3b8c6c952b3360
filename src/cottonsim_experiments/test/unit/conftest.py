"""A local Ray cluster of 2 CPUs shared by the tests that run sweeps (the engine's and the reproduce experiments')."""
import os

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))


@pytest.fixture(scope="session")
def ray_cluster(tmp_path_factory):
    """Ray started once with 2 CPUs; the workers import this folder's stub modules (sweep_stub_runs)."""
    import ray                     # a pinned requirement (requirements.txt): missing is a failure, not a skip
    markers = tmp_path_factory.mktemp("markers")
    os.environ["COTTONSIM_SWEEP_STUB_MARKERS"] = str(markers)
    os.environ["PYTHONPATH"] = HERE + os.pathsep + os.environ.get("PYTHONPATH", "")
    # Ray gives its raylet a fixed 30 s to register; on a heavily loaded machine that can pass: try again
    for attempt in range(3):
        try:
            ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
            break
        except Exception:                          # Ray raises a bare Exception for the startup timeout
            ray.shutdown()
            if attempt == 2:
                raise
    import sweep_stub_runs  # noqa: F401  (the same module the workers import)
    yield markers
    ray.shutdown()
