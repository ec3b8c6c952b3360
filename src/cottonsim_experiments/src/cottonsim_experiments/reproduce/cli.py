"""Reproduce the paper's experiments, one command each: ``rosrun cottonsim_experiments reproduce EXPERIMENT``.

  reproduce gps-route   [--seeds 0 1 2] [--real-time-factor 0] [--no-bag] [--vision on|off|both] [--resume]
                                                                           GPS route, report + plot + bag per seed
  reproduce map-route   [--seeds 0 1 2] ...                                  map-based route (AMCL on the SLAM map)
  reproduce harvest     [--seeds 0 1 2] [--lanes row|all] [--row 1] [--targets detections|ground_truth] [--vision on|off]
                                                                           the harvest on the GPS route (docs/harvest.md)
  reproduce row-spacing [--spacings 1.0 1.1 ... 1.9] [--seeds 0]            the paper's Fig. 3a study
  reproduce perception  [--synthetic-images 120]                           Tables 2 and 3 (evaluate command)
  reproduce results-doc [--doc docs/results.md] [--sections harvest ...]   the results page from the results folder
  reproduce screenshots [--bringups sim gps_navigation ...]                 headless rviz screenshots of the bringups
  reproduce sweep       --config SWEEP.yaml [--address auto|HOST:PORT] [--cpus-per-run 2] [--max-retries 2] [--resume]
                                                                           a grid of runs on Ray (docs/sweeps.md)
  reproduce all         [--seeds 0 1 2]                                    everything above, then results-doc

Results go to --results DIR (default: $COTTONSIM_RESULTS, else results/ in the current directory);
the results page to --doc (default DIR/results.md), the screenshots to --screenshot-dir (default
DIR/rviz). From the repository root, `--doc docs/results.md --screenshot-dir docs/rviz` refreshes the
committed pages.

The route seeds and the row-spacing attempts run as sweeps (docs/sweeps.md), the same code path as
`reproduce sweep`: one Ray task per bringup on a local cluster of this machine's cores (or the cluster
of --address), each reserving --cpus-per-run cores; a lost worker or a taken master port is retried
(--max-retries), --resume keeps the runs done before, and runs.csv / summary.md list the runs. Each
bringup runs on its own ROS master port (a roscore of yours is not touched); its console goes to
<run>/launch.log and a progress line counts the runs done / running / failed / left. Ctrl-C stops
every running bringup cleanly (the recorder writes what it has), keeps the finished runs and ends the
command.
"""
import argparse
import os
import sys

from cottonsim_navigation.evaluation.vision_ablation import ablation_markdown

from cottonsim_experiments.sweep.engine import EngineConfig

from ..harvest_run.route import LANE_CHOICES, LANES_ROW, TARGET_SOURCES
from . import row_spacing as rs
from .harvest import run_harvest
from .packages import RESULTS_ENV, default_results_dir
from .results_doc import SECTIONS, render_results
from .route_experiments import run_route, run_row_spacing
from .runs import Workspace, run_perception
from .screenshots import BRINGUPS, take_screenshots


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("experiment", choices=("gps-route", "map-route", "harvest", "row-spacing", "perception", "results-doc",
                                           "screenshots", "sweep", "all"))
    ap.add_argument("--results", default=None,
                    help=f"results root (default: ${RESULTS_ENV}, else results/ in the current directory)")
    ap.add_argument("--doc", default=None, help="results page to write (default: RESULTS/results.md)")
    ap.add_argument("--sections", nargs="+", choices=SECTIONS, default=None,
                    help="results-doc: render only these sections again in the page that is there (the others stay), "
                         "for a results folder that holds some experiments only")
    ap.add_argument("--seeds", type=int, nargs="+", default=None,
                    help="seeds: the GPS route seeds farm + simulator, the map route the simulator only (the map is of "
                         "the farm in sim_navigation.yaml); route runs default 0 1 2, the row-spacing study 0")
    ap.add_argument("--real-time-factor", type=float, default=0.0, help="0 = as fast as possible")
    ap.add_argument("--no-bag", action="store_true", help="route runs: do not record bags")
    ap.add_argument("--vision", choices=("on", "off", "both"), default=None,
                    help="harvest: the cameras and networks on or off (default: on with --targets detections, off "
                         "with ground_truth); route runs (default on): Cotton-Eye in the loop (on, the paper's robot: results/<route>/), the LiDAR + "
                         "GPS run (off: results/<route>_no_vision/), or both and their ablation table "
                         "(results/<route>_vision_ablation.md)")
    ap.add_argument("--lanes", choices=LANE_CHOICES, default=LANES_ROW,
                    help="harvest: one row from both its lanes (row, default) or every lane of the farm (all)")
    ap.add_argument("--row", type=int, default=1, help="harvest: the row harvested with --lanes row (default 1)")
    ap.add_argument("--targets", choices=TARGET_SOURCES, default="detections",
                    help="harvest: the harvest node's targets: the networks' detections (default) or the simulator's "
                         "truth (ground_truth, a study option)")
    ap.add_argument("--spacings", type=float, nargs="+", default=list(rs.PAPER_SPACINGS_M), help="row spacings [m]")
    ap.add_argument("--plants-per-row", type=int, default=rs.RowSpacingStudyConfig.plants_per_row,
                    help="row-spacing study: plants per row (fewer = a shorter lane, for quick checks)")
    ap.add_argument("--goal-timeout", type=float, default=rs.RowSpacingStudyConfig.goal_timeout_s,
                    help="row-spacing study: sim seconds per waypoint before it counts as failed")
    ap.add_argument("--waypoints", default=None,
                    help="route runs: another route file than the paper's route (e.g. a short route for checks)")
    ap.add_argument("--original-data", default=os.environ.get("COTTONSIM_PAPER_DATA"),
                    help="the paper's labelled images (a folder with Segmentation/ and Detection/); default: "
                         "$COTTONSIM_PAPER_DATA")
    ap.add_argument("--config", default=None, help="sweep: the sweep file (YAML; see docs/sweeps.md)")
    ap.add_argument("--address", default=None,
                    help="sweep and the route / row-spacing runs: a Ray cluster to run on ('auto' or HOST:PORT); "
                         "default: a local cluster of this machine's cores")
    ap.add_argument("--cpus-per-run", type=int, default=2,
                    help="cores each run reserves (and its NUMBA/OMP threads); default 2")
    ap.add_argument("--max-retries", type=int, default=2,
                    help="extra attempts of a run whose worker died or whose master port was taken")
    ap.add_argument("--resume", action="store_true",
                    help="keep the finished runs (of the sweep, or of the route / row-spacing runs), run the rest; "
                         "without it a route or row-spacing run done before is run again")
    ap.add_argument("--local-cpus", type=int, default=None,
                    help="cores of the local cluster (default: this machine's)")
    ap.add_argument("--synthetic-images", type=int, default=120,
                    help="held-out synthetic test frames per task (0: skip the synthetic tables)")
    ap.add_argument("--bringups", nargs="+", default=None,
                    help="screenshots: which bringups (default all: " + " ".join(BRINGUPS) + ")")
    ap.add_argument("--screenshot-dir", default=None, help="where the screenshots go (default: RESULTS/rviz)")
    a = ap.parse_args(argv)
    results = os.path.abspath(a.results) if a.results else default_results_dir()
    doc = os.path.abspath(a.doc) if a.doc else os.path.join(results, "results.md")
    try:
        if a.experiment == "sweep":
            if not a.config:
                raise ValueError("sweep needs --config SWEEP.yaml (see docs/sweeps.md)")
            from cottonsim_experiments.sweep.command import sweep_command
            return sweep_command(a.config, results, a.address, a.cpus_per_run, a.max_retries, a.resume,
                                 a.local_cpus)
        ws = Workspace(results=results)
        engine = EngineConfig(address=a.address, cpus_per_run=a.cpus_per_run, max_retries=a.max_retries,
                              resume=a.resume, replace_finished=not a.resume, local_cpus=a.local_cpus)
        for experiment in ("gps_route", "map_route"):
            if a.experiment in (experiment.replace("_", "-"), "all"):
                _route(ws, experiment, a, engine)
        if a.experiment == "harvest":
            if a.vision == "both":
                raise ValueError("harvest takes --vision on or off")
            if a.waypoints:
                raise ValueError("harvest builds its route from --lanes and --row; --waypoints is for gps-route "
                                 "and map-route")
            run_harvest(ws, a.seeds or [0, 1, 2], lanes=a.lanes, row=a.row, targets=a.targets,
                        vision=None if a.vision is None else a.vision == "on", real_time_factor=a.real_time_factor,
                        record_bag=not a.no_bag, engine=engine)
        if a.experiment in ("row-spacing", "all"):
            run_row_spacing(ws, rs.RowSpacingStudyConfig(spacings_m=tuple(a.spacings),
                                                         plants_per_row=a.plants_per_row,
                                                         goal_timeout_s=a.goal_timeout),
                            a.real_time_factor, seeds=a.seeds or [0], engine=engine)
        if a.experiment in ("perception", "all"):
            if not a.original_data:
                raise ValueError("perception needs the paper's labelled images: give --original-data DIR "
                                 "(or set COTTONSIM_PAPER_DATA) with Segmentation/ and Detection/ inside")
            if not os.path.isdir(a.original_data):
                raise ValueError(f"--original-data {a.original_data!r} is not a folder")
            run_perception(ws, a.original_data, synthetic_images=a.synthetic_images)
        if a.experiment == "screenshots":
            shots = take_screenshots(a.bringups or list(BRINGUPS), a.screenshot_dir or os.path.join(results, "rviz"))
            if not all(r.ok for r in shots):
                return 1
        if a.experiment in ("results-doc", "all"):
            render_results(ws.results, doc, a.sections if a.experiment == "results-doc" else None)
            print(f"wrote {doc}")
    except ValueError as exc:
        print(f"reproduce: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\nreproduce: interrupted; finished runs are kept under " + results, file=sys.stderr)
        return 130
    return 0



def _route(ws: Workspace, experiment: str, a, engine: EngineConfig) -> None:
    """One route in the --vision mode(s); with both, the ablation table next to the two result folders."""
    modes = {"on": (True,), "off": (False,), "both": (False, True)}[a.vision or "on"]
    summaries = {vision: run_route(ws, experiment, a.seeds or [0, 1, 2], a.real_time_factor, record_bag=not a.no_bag,
                                   waypoints=a.waypoints, vision=vision, engine=engine) for vision in modes}
    if len(summaries) == 2:
        lines = ablation_markdown(summaries[True], summaries[False])
        path = os.path.join(ws.results, f"{experiment}_vision_ablation.md")
        with open(path, "w", encoding="utf-8") as fh:
            fh.write("\n".join(lines) + "\n")
        print("\n".join(lines) + f"\nwrote {path}", flush=True)
