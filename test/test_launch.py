"""launch/rig_identification.launch.py without ROS's ``launch`` (not installable from pip here).

The file must compile, name only executables that setup.py installs (console scripts whose
functions exist) and only parameter files that exist and parse as ROS parameter files for
the node names it uses; its launch-independent part (``node_specs``) picks the nodes and
parameters for the launch arguments.  That colcon installs it is checked in
test_colcon_build.py.
"""
from __future__ import annotations

import ast
import importlib
import importlib.util
import py_compile
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
LAUNCH = REPO / "launch" / "rig_identification.launch.py"
EXPERIMENT = REPO / "config" / "rigs" / "default.yaml"


@pytest.fixture(scope="module")
def launch_module():
    py_compile.compile(str(LAUNCH), doraise=True)
    # as ros2 launch loads it: executed as a module that is not registered in sys.modules
    spec = importlib.util.spec_from_file_location("python_launch_file", LAUNCH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)  # imports nothing from launch at module level
    return mod


def console_scripts() -> dict[str, str]:
    """name -> "module:function" of setup.py's console scripts (read with ast, not run)."""
    tree = ast.parse((REPO / "setup.py").read_text())
    nodes = next(ast.literal_eval(n.value) for n in ast.walk(tree)
                 if isinstance(n, ast.Assign) and any(getattr(t, "id", "") == "NODES" for t in n.targets))
    scripts = dict(nodes)
    for n in ast.walk(tree):
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and " = rig_identification." in n.value:
            name, target = (x.strip() for x in n.value.split("="))
            scripts[name] = target
    return scripts


def test_launch_file_defines_generate_launch_description():
    tree = ast.parse(LAUNCH.read_text())
    funcs = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert "generate_launch_description" in funcs
    # launch / launch_ros only inside it: the module imports on a machine without ROS's launch
    top = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))]
    names = {a.name for n in top for a in n.names} | {n.module for n in top if isinstance(n, ast.ImportFrom)}
    assert not {x for x in names if x and x.split(".")[0] in ("launch", "launch_ros")}, names


def test_every_executable_is_a_console_script_of_setup_py(launch_module):
    scripts = console_scripts()
    for executable in launch_module.NODES:
        assert executable in scripts, f"{executable} is not a console script of setup.py"
        module, func = scripts[executable].split(":")
        assert callable(getattr(importlib.import_module(module), func)), scripts[executable]


def test_every_parameter_file_exists_and_is_a_ros_parameter_file_of_its_node(launch_module):
    specs = launch_module.node_specs({"sensor_driver": "true", "record": "/tmp/x", "visualizer": "true"}, REPO)
    assert [s.executable for s in specs] == ["sensor_driver", "tracker", "preprocessor", "identifier",
                                             "rig_visualizer", "recorder"]
    for s in specs:
        path = Path(s.parameters[0])
        assert path.is_file(), path
        assert path.parent == REPO / "config" / "params"
        d = yaml.safe_load(path.read_text())
        assert list(d) == [s.name], f"{path}: top-level key {list(d)}, the launch file names the node {s.name!r}"
        params = d[s.name]["ros__parameters"]
        assert isinstance(params, dict) and params, path
        # values a ROS parameter can hold (no nested mappings; lists of one type)
        for k, v in params.items():
            assert not isinstance(v, dict), (path, k)
            if isinstance(v, list):
                assert len({type(x) for x in v}) == 1, (path, k, v)
        for extra in s.parameters[1:]:
            assert set(extra) <= set(params), f"{s.name}: launch sets {set(extra) - set(params)} not in {path}"


def test_node_specs_follow_the_arguments(launch_module, tmp_path):
    specs = {s.executable: s for s in launch_module.node_specs({}, REPO)}
    assert set(specs) == {"tracker", "preprocessor", "identifier", "rig_visualizer"}  # defaults
    assert specs["tracker"].parameters[1] == {"rig": str(EXPERIMENT)}
    specs = {s.executable: s for s in launch_module.node_specs(
        {"sensor_driver": "true", "rate": "3", "visualizer": "false", "params_file": "/lab/frames.yaml"}, REPO)}
    assert set(specs) == {"sensor_driver", "tracker", "preprocessor", "identifier"}
    drv = specs["sensor_driver"].parameters[1]
    assert drv["experiment"] == str(EXPERIMENT) and drv["rate"] == 3.0
    assert "/rig/imu:2" in drv["wait_for"] and "/rig/load_cells/*:3" in drv["wait_for"]
    assert all(s.parameters[-1] == "/lab/frames.yaml" for s in specs.values())
    # a recording folder is replayed; a plain rig.yaml cannot be simulated
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "rig.yaml").write_text(yaml.safe_dump(yaml.safe_load(EXPERIMENT.read_text())["rig"]))
    specs = {s.executable: s for s in launch_module.node_specs(
        {"sensor_driver": "true", "rig": str(rec), "record": str(tmp_path / "out")}, REPO)}
    assert specs["sensor_driver"].parameters[1]["recording"] == str(rec)
    assert "/rig/imu:3" in specs["sensor_driver"].parameters[1]["wait_for"]  # + the recorder
    assert specs["recorder"].parameters[1] == {"rig": str(rec), "output": str(tmp_path / "out")}
    with pytest.raises(ValueError, match="is a rig.yaml"):
        launch_module.node_specs({"sensor_driver": "true", "rig": str(rec / "rig.yaml")}, REPO)
    with pytest.raises(ValueError, match="visualizer"):
        launch_module.node_specs({"visualizer": "maybe"}, REPO)
