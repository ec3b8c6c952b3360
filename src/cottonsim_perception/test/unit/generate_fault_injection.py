"""A fault for the dataset generator's Ray test: the first attempt of one scene range loses its worker.

Ray runs :func:`install` in every worker process it starts (``runtime_env={"worker_process_setup_hook":
"generate_fault_injection.install"}``, with this folder on the workers' PYTHONPATH). It wraps the
range renderer of cottonsim_perception.data.generate.ray_engine so that every attempt of a range is
noted in a marker folder, and the first attempt of the range named in that folder's ``doomed`` file
(none when it is missing) ends its worker process mid-range, as a killed or crashed worker would.
"""
import os

MARKERS_ENV = "COTTONSIM_GENERATE_FAULT_MARKERS"
DOOMED_FILE = "doomed"          # in the marker folder: "<split>:<farm seed>:<task>:<scene_lo>" of the range to fail


def range_name(job, task, scene_lo) -> str:
    return f"{job.split}:{job.farm_seed}:{task}:{scene_lo}"


def _marker(name: str) -> str:
    return name.replace(":", "_")


def attempts(markers: str, name: str) -> int:
    """How many attempts of range ``name`` started."""
    prefix = _marker(name) + ".attempt"
    return sum(1 for f in os.listdir(markers) if f.startswith(prefix))


def install() -> None:
    from cottonsim_perception.data.generate import ray_engine

    markers = os.environ[MARKERS_ENV]
    render = ray_engine.render_scene_range

    def render_with_fault(config, job, task, scene_lo, scene_hi, *args, **kwargs):
        name = range_name(job, task, scene_lo)
        try:
            with open(os.path.join(markers, DOOMED_FILE)) as fh:
                doomed = fh.read().strip()
        except OSError:
            doomed = None
        attempt = attempts(markers, name) + 1
        open(os.path.join(markers, f"{_marker(name)}.attempt{attempt}"), "w").close()
        images = list(render(config, job, task, scene_lo, scene_hi, *args, **kwargs))
        if name == doomed and attempt == 1:
            os._exit(1)                     # the worker dies with the range rendered but not returned
        return images

    ray_engine.render_scene_range = render_with_fault
