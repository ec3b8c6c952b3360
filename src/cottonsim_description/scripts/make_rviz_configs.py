#!/usr/bin/env python3
"""Write the rviz configuration of each bringup from one set of display definitions.

One file per bringup, each in the package that owns the bringup:
  cottonsim_navigation/rviz/navigation.rviz   gps_navigation.launch, map_navigation.launch (fixed frame map)
  cottonsim_navigation/rviz/mapping.rviz      mapping.launch (the map as SLAM builds it)
  cottonsim_perception/rviz/perception.rviz   perception_demo.launch (front depth cloud in colour, the
                                              row-centring overlay: masks, fitted lines, correction)
(cottonsim_description/rviz/cottonsim.rviz, the simulator's own view, is kept by hand.)

  python3 src/cottonsim_description/scripts/make_rviz_configs.py      # rewrites the three files

Generated so that the displays look the same in every view and a topic renamed
in one place is renamed everywhere; the files are checked in.
"""
import pathlib

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[3]


def grid():
    return {"Class": "rviz/Grid", "Name": "Grid", "Enabled": True, "Value": True, "Alpha": 0.3,
            "Cell Size": 1, "Plane Cell Count": 60, "Color": "160; 160; 164", "Reference Frame": "<Fixed Frame>",
            "Line Style": {"Line Width": 0.03, "Value": "Lines"}, "Normal Cell Count": 0, "Plane": "XY",
            "Offset": {"X": 0, "Y": 0, "Z": 0}}


def occupancy(name, topic, scheme="map", alpha=0.7):
    return {"Class": "rviz/Map", "Name": name, "Topic": topic, "Enabled": True, "Value": True, "Alpha": alpha,
            "Color Scheme": scheme, "Draw Behind": scheme == "map", "Unreliable": False, "Use Timestamp": False}


def robot_model():
    return {"Class": "rviz/RobotModel", "Name": "Robot", "Enabled": True, "Value": True, "Alpha": 1,
            "Robot Description": "robot_description", "TF Prefix": "", "Update Interval": 0,
            "Visual Enabled": True, "Collision Enabled": False}


def cloud(name, topic, size_px=2):
    return {"Class": "rviz/PointCloud2", "Name": name, "Topic": topic, "Enabled": True, "Value": True, "Alpha": 1,
            "Style": "Points", "Size (Pixels)": size_px, "Size (m)": 0.01, "Color Transformer": "AxisColor",
            "Axis": "Z", "Use rainbow": True, "Decay Time": 0, "Position Transformer": "XYZ", "Queue Size": 10,
            "Selectable": True, "Use Fixed Frame": True, "Unreliable": False,
            "Autocompute Value Bounds": {"Value": True, "Max Value": 1, "Min Value": 0}}


def rgb_cloud(name, topic):
    c = cloud(name, topic, 2)
    c["Color Transformer"] = "RGB8"
    return c


def scan(name, topic, color="255; 0; 0"):
    return {"Class": "rviz/LaserScan", "Name": name, "Topic": topic, "Enabled": True, "Value": True, "Alpha": 1,
            "Style": "Points", "Size (Pixels)": 3, "Size (m)": 0.03, "Color Transformer": "FlatColor",
            "Color": color, "Decay Time": 0, "Position Transformer": "XYZ", "Queue Size": 10, "Selectable": True,
            "Use Fixed Frame": True, "Unreliable": False}


def path(name, topic, color):
    return {"Class": "rviz/Path", "Name": name, "Topic": topic, "Enabled": True, "Value": True, "Alpha": 1,
            "Color": color, "Line Style": "Billboards", "Line Width": 0.05, "Buffer Length": 1,
            "Pose Style": "None", "Queue Size": 10, "Unreliable": False, "Offset": {"X": 0, "Y": 0, "Z": 0.05}}


def pose(name, topic, color):
    return {"Class": "rviz/Pose", "Name": name, "Topic": topic, "Enabled": True, "Value": True, "Alpha": 1,
            "Color": color, "Shape": "Arrow", "Shaft Length": 0.6, "Shaft Radius": 0.05, "Head Length": 0.25,
            "Head Radius": 0.12, "Queue Size": 10, "Unreliable": False}


def pose_array(name, topic):
    return {"Class": "rviz/PoseArray", "Name": name, "Topic": topic, "Enabled": True, "Value": True, "Alpha": 1,
            "Color": "255; 25; 0", "Shape": "Arrow (Flat)", "Arrow Length": 0.2, "Queue Size": 10,
            "Unreliable": False}


def image(name, topic):
    return {"Class": "rviz/Image", "Name": name, "Image Topic": topic, "Enabled": True, "Value": True,
            "Transport Hint": "raw", "Normalize Range": True, "Queue Size": 2, "Unreliable": False,
            "Max Value": 1, "Min Value": 0, "Median window": 5}


def top_down(scale_px_per_m, target="base_link", angle=0.0):
    return {"Class": "rviz/TopDownOrtho", "Name": "Current View", "Scale": scale_px_per_m, "Angle": angle,
            "Target Frame": target, "X": 0, "Y": 0, "Near Clip Distance": 0.01, "Invert Z Axis": False}


def orbit(target="base_link", distance=6.0, pitch=0.6, yaw=3.14):
    return {"Class": "rviz/Orbit", "Name": "Current View", "Target Frame": target, "Distance": distance,
            "Pitch": pitch, "Yaw": yaw, "Field of View": 0.785398, "Focal Point": {"X": 1.5, "Y": 0, "Z": 0.3},
            "Focal Shape Fixed Size": True, "Focal Shape Size": 0.05, "Near Clip Distance": 0.01,
            "Invert Z Axis": False}


# Qt's saved dock layout (QMainWindow::saveState) of cottonsim.rviz: the Displays panel top left, the
# image display named "Primary camera" below it, Views on the right, Time at the bottom. rviz places a
# panel by its name, so every generated view names its one image display "Primary camera".
MAIN_WINDOW_STATE = (
    "000000ff00000000fd00000003000000000000014a000002cdfc0200000002fb000000100044006900730070006c0061007900730100"
    "000011000001c30000001700fffffffb0000001c005000720069006d006100720079002000630061006d00650072006101000001da00"
    "0001040000001700ffffff0000000100000104000002cdfc0200000001fb0000000a005600690065007700730100000011000002cd00"
    "00001700ffffff00000003000005000000003cfc0100000001fb0000000800540069006d00650100000000000005000000003e00ffff"
    "ff000002a6000002cd00000004000000040000000800000008fc0000000100000002000000010000000a0054006f006f006c00730100"
    "000000ffffffff0000000000000000")


def config(title, displays, fixed_frame, view, width=1280, height=800):
    """A complete rviz 1.14 configuration."""
    return {
        "Panels": [{"Class": "rviz/Displays", "Name": "Displays", "Help Height": 0, "Tree Height": 420,
                    "Splitter Ratio": 0.5, "Property Tree Widget": {"Expanded": ["/Global Options1"]}},
                   {"Class": "rviz/Views", "Name": "Views", "Splitter Ratio": 0.5, "Expanded": ["/Current View1"]},
                   {"Class": "rviz/Time", "Name": "Time", "SyncMode": 0, "SyncSource": ""}],
        "Preferences": {"PromptSaveOnExit": False},
        "Toolbars": {"toolButtonStyle": 2},
        "Visualization Manager": {
            "Class": "", "Name": "root", "Enabled": True, "Value": True,
            "Displays": displays,
            "Global Options": {"Background Color": "48; 48; 48", "Default Light": True,
                               "Fixed Frame": fixed_frame, "Frame Rate": 15},
            "Tools": [{"Class": "rviz/Interact", "Hide Inactive Objects": True}, {"Class": "rviz/MoveCamera"},
                      {"Class": "rviz/Select"}, {"Class": "rviz/Measure"},
                      {"Class": "rviz/SetInitialPose", "Topic": "/initialpose", "X std deviation": 0.5,
                       "Y std deviation": 0.5, "Theta std deviation": 0.2617993950843811},
                      {"Class": "rviz/SetGoal", "Topic": "/move_base_simple/goal"}],
            "Views": {"Current": view, "Saved": None},
        },
        "Window Geometry": {"Width": width, "Height": height, "X": 0, "Y": 0, "Hide Left Dock": False,
                            "Hide Right Dock": True, "Displays": {"collapsed": False},
                            "Primary camera": {"collapsed": False}, "Views": {"collapsed": True},
                            "Time": {"collapsed": False}, "QMainWindow State": MAIN_WINDOW_STATE},
        "_title": title,
    }


def navigation():
    displays = [grid(),
                occupancy("Map", "/map"),
                occupancy("Global costmap", "/move_base/global_costmap/costmap", "costmap", 0.35),
                occupancy("Local costmap", "/move_base/local_costmap/costmap", "costmap", 0.5),
                robot_model(),
                cloud("LiDAR obstacles (PassThrough)", "/passthrough/output", 3),
                scan("Scan", "/scan"),
                path("Global plan (navfn)", "/move_base/NavfnROS/plan", "25; 255; 0"),
                path("Local plan (DWA)", "/move_base/DWAPlannerROS/local_plan", "0; 170; 255"),
                pose("Current goal", "/move_base/current_goal", "255; 170; 0"),
                pose_array("AMCL particles (map mode)", "/particlecloud"),
                image("Primary camera", "/realsense_p/color/image_raw")]
    return config("GPS and map-based navigation", displays, "map", top_down(45.0))


def mapping():
    displays = [grid(),
                occupancy("SLAM map", "/map"),
                robot_model(),
                scan("Scan (360 deg)", "/scan_360", "255; 60; 60"),
                path("Global plan (navfn)", "/move_base/NavfnROS/plan", "25; 255; 0"),
                pose("Current goal", "/move_base/current_goal", "255; 170; 0")]
    return config("SLAM mapping", displays, "map", top_down(22.0, target="map"))


def perception():
    displays = [grid(),
                robot_model(),
                rgb_cloud("Front depth cloud (RGB)", "/realsense_p/depth/color/points"),
                image("Primary camera", "/row_centring/overlay")]
    return config("Cotton-Eye perception", displays, "base_link", orbit())


TARGETS = {
    "src/cottonsim_navigation/rviz/navigation.rviz": navigation,
    "src/cottonsim_navigation/rviz/mapping.rviz": mapping,
    "src/cottonsim_perception/rviz/perception.rviz": perception,
}


def main() -> None:
    for rel, make in TARGETS.items():
        data = make()
        title = data.pop("_title")
        out = ROOT / rel
        out.parent.mkdir(parents=True, exist_ok=True)
        header = (f"# rviz configuration: {title}.\n"
                  f"# Generated by src/cottonsim_description/scripts/make_rviz_configs.py: edit that, not this file.\n")
        out.write_text(header + yaml.safe_dump(data, sort_keys=False, default_flow_style=False))
        print(f"wrote {rel}")


if __name__ == "__main__":
    main()
