"""The rig_identification node graph: ``ros2 launch rig_identification rig_identification.launch.py``.

Starts tracker, preprocessor and identifier (and, by the arguments below, sensor_driver,
rig_visualizer and recorder), each with its parameter file from the package's
``config/params/`` (``<node>.yaml``, node names as in those files) and ``rig``.

Arguments (``name:=value``):
  rig            rig description: rig.yaml, recording folder or experiment file
                 (default: the package's config/rigs/default.yaml, thesis case 16)
  sensor_driver  true: also start sensor_driver, which simulates ``rig`` (an experiment file)
                 or replays it (a recording folder) once the consumers are subscribed
                 (default false: the lab's own drivers publish /rig/...)
  rate           real-time factor of sensor_driver (default 1.0)
  visualizer     true: start rig_visualizer (/rig/transform, /tf, /rig/markers; default true)
  record         a folder: start recorder writing the recording there (default "": none)
  params_file    a ROS parameter file given to every node after its own (e.g. frame ids for
                 all nodes: ``/**: {ros__parameters: {imu_frame: imu_link}}``; default "")
  params_dir     folder of the nodes' parameter files (default: the package's config/params)

Topics are remapped as usual for ``ros2 launch``: wrap this file in your own launch file and
give ``remappings`` there, or remap per node with ``--ros-args -r`` when running it alone
(docs/ros.md).

The launch-independent part (:func:`node_specs`) imports nothing from ``launch``: the tests
check it without a ROS installation.  (No ``from __future__ import annotations``: ``ros2
launch`` executes this file as a module it does not register in ``sys.modules``, and
dataclasses with string annotations look their module up there.)
"""

from dataclasses import dataclass, field
from pathlib import Path

import yaml

PACKAGE = "rig_identification"

#: executable (a console script of setup.py) -> (node name, parameter file in config/params)
NODES = {
    "sensor_driver": ("sensor_driver", "sensor_driver.yaml"),
    "tracker": ("tracker", "tracker.yaml"),
    "preprocessor": ("preprocessor", "preprocessor.yaml"),
    "identifier": ("identifier", "identifier.yaml"),
    "rig_visualizer": ("rig_visualizer", "rig_visualizer.yaml"),
    "recorder": ("recorder", "recorder.yaml"),
}

#: launch argument -> (default, description); "" defaults of rig and params_dir mean "the package's"
ARGUMENTS = {
    "rig": ("", "rig description: rig.yaml, recording folder or experiment file "
                "(default: the package's config/rigs/default.yaml)"),
    "sensor_driver": ("false", "true: simulate (experiment file) or replay (recording folder) `rig` with sensor_driver"),
    "rate": ("1.0", "real-time factor of sensor_driver"),
    "visualizer": ("true", "true: start rig_visualizer (/rig/transform, /tf, /rig/markers)"),
    "record": ("", "a folder: record the rig topics there with recorder (must not exist)"),
    "params_file": ("", "a ROS parameter file given to every node after its own"),
    "params_dir": ("", "folder of the nodes' parameter files (default: the package's config/params)"),
}


@dataclass
class NodeSpec:
    """One node to start: console script, node name, parameters (files, then dicts)."""

    executable: str
    name: str
    parameters: list = field(default_factory=list)


def is_true(value: str, name: str) -> bool:
    """A launch argument's boolean (true/false, 1/0, yes/no); ValueError naming the argument."""
    v = str(value).strip().lower()
    if v in ("true", "1", "yes", "on"):
        return True
    if v in ("false", "0", "no", "off", ""):
        return False
    raise ValueError(f"launch argument {name}:={value!r}: expected true or false")


def driver_source(rig: Path) -> dict:
    """sensor_driver's source parameter for ``rig``: ``recording`` for a folder, ``experiment``
    for an experiment file (a YAML mapping with ``rig:``); ValueError for a plain rig.yaml
    (nothing to simulate)."""
    if rig.is_dir():
        return {"recording": str(rig)}
    try:
        d = yaml.safe_load(rig.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as e:
        raise ValueError(f"launch argument rig:={rig}: cannot read it ({e})") from None
    if isinstance(d, dict) and "rig" in d and "gravity" not in d:
        return {"experiment": str(rig)}
    raise ValueError(f"launch argument rig:={rig} is a rig.yaml: sensor_driver:=true needs an experiment file "
                     "(simulated) or a recording folder (replayed)")


def node_specs(config: dict[str, str], share: Path) -> list[NodeSpec]:
    """The nodes to start for the launch arguments ``config`` (missing ones: their
    defaults), with the package's share folder ``share`` (config/params, config/rigs).
    Raises ValueError naming a bad argument."""
    cfg = {k: str(config.get(k, default)) for k, (default, _) in ARGUMENTS.items()}
    params_dir = Path(cfg["params_dir"]) if cfg["params_dir"] else share / "config" / "params"
    rig = Path(cfg["rig"]) if cfg["rig"] else share / "config" / "rigs" / "default.yaml"
    extra = [cfg["params_file"]] if cfg["params_file"] else []
    record = cfg["record"]
    driver = is_true(cfg["sensor_driver"], "sensor_driver")
    visual = is_true(cfg["visualizer"], "visualizer")

    def spec(executable: str, params: dict) -> NodeSpec:
        name, file = NODES[executable]
        return NodeSpec(executable, name, [str(params_dir / file), params, *extra])

    specs = []
    if driver:
        try:
            rate = float(cfg["rate"])
        except ValueError:
            raise ValueError(f"launch argument rate:={cfg['rate']!r}: expected a number") from None
        readers = 1 if record else 0  # the recorder reads the raw streams too
        wait_for = [f"/rig/imu:{2 + readers}", f"/rig/load_cells/*:{3 + readers}", "/rig/pose:1"]
        specs.append(spec("sensor_driver", {**driver_source(rig), "rate": rate, "wait_for": wait_for}))
    for executable in ("tracker", "preprocessor", "identifier"):
        specs.append(spec(executable, {"rig": str(rig)}))
    if visual:
        specs.append(spec("rig_visualizer", {"rig": str(rig)}))
    if record:
        specs.append(spec("recorder", {"rig": str(rig), "output": record}))
    return specs


def generate_launch_description():
    """The LaunchDescription (``ros2 launch`` calls this; needs launch and launch_ros)."""
    from ament_index_python.packages import get_package_share_directory
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    share = Path(get_package_share_directory(PACKAGE))

    def nodes(context):
        config = {k: LaunchConfiguration(k).perform(context) for k in ARGUMENTS}
        return [Node(package=PACKAGE, executable=s.executable, name=s.name, parameters=s.parameters,
                     output="screen", emulate_tty=True)
                for s in node_specs(config, share)]

    return LaunchDescription([DeclareLaunchArgument(k, default_value=d, description=text)
                              for k, (d, text) in ARGUMENTS.items()] + [OpaqueFunction(function=nodes)])
