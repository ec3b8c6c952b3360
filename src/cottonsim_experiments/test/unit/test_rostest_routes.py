"""The system rostests' route files agree with the farm they drive through."""
import pathlib

import numpy as np
import yaml

from cottonsim_navigation.waypoints.files import load_gps_waypoints
from cottonsim_world.config_io import simulator_config_from_dict
from cottonsim_world.farm.export import route_in_frame
from cottonsim_world.farm.generator import generate_farm
from cottonsim_world.geodesy import HectorGeodesy

ROSTEST_DIR = pathlib.Path(__file__).resolve().parents[1] / "rostest"


def test_off_meridian_rostest_route_is_the_default_farm_route_at_its_reference():
    """gps_route_lubbock.txt (gps_navigator_off_meridian.test) = the farm's first 6 route points
    through the simulator's GPS at nav_ci_lubbock.yaml's reference, as generate_farm writes them."""
    rostest_dir = ROSTEST_DIR
    with open(rostest_dir / "nav_ci_lubbock.yaml", encoding="utf-8") as fh:
        settings = yaml.safe_load(fh)
    geodesy = HectorGeodesy(*simulator_config_from_dict(settings).geodesy_reference)
    assert (geodesy.reference_latitude_deg, geodesy.reference_longitude_deg) == (33.4, -101.0)
    wps = load_gps_waypoints(rostest_dir / "gps_route_lubbock.txt")
    x, y, _ = geodesy.geodetic_to_world(np.array([w.lat for w in wps]), np.array([w.lon for w in wps]))
    route = route_in_frame(generate_farm(simulator_config_from_dict(settings).farm))[:6, :2]
    np.testing.assert_allclose(np.stack([x, y], axis=1), route, atol=1e-6)
