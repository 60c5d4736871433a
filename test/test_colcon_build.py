"""The package builds as a ROS 2 ament_python package with colcon, and its nodes start.

The package's files are copied into ``<tmp>/ws/src/rig_identification`` and built with the
venv's ``colcon`` (colcon-ros handles ament_python).  Every node executable must land in
``install/rig_identification/lib/rig_identification/`` (where ``ros2 run`` looks), answer
``--help``, and a node started from the install space must come up, find the installed
data files through the ament index, and stop cleanly on SIGINT.  ``install/setup.bash``
is sourced in a child bash only (nothing is sourced in this process).
"""
from __future__ import annotations

import os
import random
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
VENV_BIN = Path(sys.executable).parent
NODES = ("sensor_driver", "tracker", "preprocessor", "identifier", "mass_properties_client", "recorder",
         "rig_visualizer", "demo", "rig-record")
PACKAGE_FILES = ("setup.py", "setup.cfg", "package.xml", "resource", "rig_identification", "config", "launch")
EXEC_DEPENDS = {"rclpy", "sensor_msgs", "geometry_msgs", "std_srvs", "python3-numpy", "python3-scipy",
                "python3-rosbags-pip", "python3-numba"}


def test_package_xml_is_format_3_with_the_exec_depends():
    root = ET.parse(REPO / "package.xml").getroot()
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == "rig_identification"
    deps = {e.text.strip() for e in root.findall("exec_depend")}
    missing = EXEC_DEPENDS - deps
    assert not missing, f"package.xml lacks <exec_depend> {sorted(missing)}"
    assert root.find("export/build_type").text.strip() == "ament_python"


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    colcon = shutil.which("colcon", path=str(VENV_BIN)) or shutil.which("colcon")
    if colcon is None:
        pytest.fail("colcon is not installed (requirements.txt: colcon-common-extensions, colcon-ros)")
    ws = tmp_path_factory.mktemp("ws")
    src = ws / "src" / "rig_identification"
    src.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")
    for name in PACKAGE_FILES:
        p = REPO / name
        if p.is_dir():
            shutil.copytree(p, src / name, ignore=ignore)
        else:
            shutil.copy2(p, src / name)
    env = dict(os.environ)
    env["PATH"] = f"{VENV_BIN}{os.pathsep}{env.get('PATH', '')}"
    for var in ("AMENT_PREFIX_PATH", "COLCON_PREFIX_PATH", "PYTHONPATH"):
        env.pop(var, None)
    t0 = time.monotonic()
    p = subprocess.run([colcon, "build", "--base-paths", "src", "--event-handlers", "console_direct-"],
                       cwd=ws, env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, f"colcon build failed:\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}"
    print(f"colcon build: {time.monotonic() - t0:.1f} s")
    return ws, env


def sourced(ws: Path, env: dict, command: str, timeout: float = 60.0, **kw) -> subprocess.CompletedProcess:
    """Run ``command`` in bash after ``source install/setup.bash``."""
    return subprocess.run(["bash", "-c", f"source install/setup.bash && {command}"], cwd=ws, env=env,
                          capture_output=True, text=True, timeout=timeout, **kw)


def test_every_node_executable_is_installed(workspace):
    ws, env = workspace
    lib = ws / "install" / "rig_identification" / "lib" / "rig_identification"
    for name in NODES:
        exe = lib / name
        assert exe.is_file(), f"{exe} missing (setup.cfg script_dir?)"
        assert os.access(exe, os.X_OK), f"{exe} is not executable"
    share = ws / "install" / "rig_identification" / "share"
    assert (share / "ament_index" / "resource_index" / "packages" / "rig_identification").is_file()
    assert (share / "rig_identification" / "package.xml").is_file()
    assert (share / "rig_identification" / "config" / "rigs" / "default.yaml").is_file()
    assert sorted(p.name for p in (share / "rig_identification" / "config" / "params").glob("*.yaml")) == \
        ["identifier.yaml", "preprocessor.yaml", "recorder.yaml", "rig_visualizer.yaml", "sensor_driver.yaml",
         "tracker.yaml"]
    # where `ros2 launch rig_identification rig_identification.launch.py` looks
    launch = share / "rig_identification" / "launch" / "rig_identification.launch.py"
    assert launch.is_file(), f"{launch} missing (setup.py data_files)"
    assert launch.read_text() == (REPO / "launch" / "rig_identification.launch.py").read_text()


def test_every_node_answers_help(workspace):
    """Every installed executable answers --help (started together: each is an interpreter
    start and the node's imports, ~1-2 s of CPU, and the machine has two cores)."""
    ws, env = workspace
    procs = {name: subprocess.Popen(["bash", "-c", "source install/setup.bash && "
                                     f"install/rig_identification/lib/rig_identification/{name} --help"],
                                    cwd=ws, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for name in NODES}
    for name, p in procs.items():
        stdout, stderr = p.communicate(timeout=60)
        assert p.returncode == 0, (name, stdout, stderr)
        assert "usage" in stdout.lower(), (name, stdout)
        # plain text for a terminal, not the docstring's reStructuredText
        assert "``" not in stdout and ":class:`" not in stdout and ":func:`" not in stdout, (name, stdout)


def test_installed_code_and_data_are_used(workspace):
    ws, env = workspace
    p = sourced(ws, env, f"{sys.executable} -c 'import rig_identification.nodes.environment as c; "
                         "print(c.__file__); print(c.default_experiment())'")
    assert p.returncode == 0, p.stderr
    code, data = p.stdout.split()
    install = str(ws / "install" / "rig_identification")
    assert code.startswith(install), f"imported {code}, not the installed package"
    assert data == f"{install}/share/rig_identification/config/rigs/default.yaml"


def test_installed_nodes_come_up_and_stop_on_sigint(workspace):
    ws, env = workspace
    env = dict(env, ROS_DOMAIN_ID=str(random.Random().randint(100, 199)),
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", PYTHONUNBUFFERED="1")
    share = ws / "install" / "rig_identification" / "share" / "rig_identification"
    # a rig.yaml from the installed default experiment
    rig = ws / "rig.yaml"
    p = sourced(ws, env, f"{sys.executable} -c 'import yaml, sys; "
                         f"d = yaml.safe_load(open(\"{share}/config/rigs/default.yaml\"))[\"rig\"]; "
                         f"yaml.safe_dump(d, open(\"{rig}\", \"w\"))'")
    assert p.returncode == 0, p.stderr
    lib = "install/rig_identification/lib/rig_identification"
    procs, logs = {}, {}
    for name in ("tracker", "preprocessor", "identifier"):
        logs[name] = ws / f"{name}.log"
        with open(logs[name], "wb") as out:
            procs[name] = subprocess.Popen(
                ["bash", "-c", f"source install/setup.bash && exec {lib}/{name} --ros-args "
                               f"--params-file {share}/config/params/{name}.yaml -p rig:={rig}"],
                cwd=ws, env=env, stdout=out, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 60
        up = set()
        while time.monotonic() < deadline and len(up) < len(procs):
            for n, pr in procs.items():
                text = logs[n].read_text(errors="replace")
                if "ready" in text:
                    up.add(n)
                assert pr.poll() is None, f"{n} exited:\n{text}"
            time.sleep(0.2)
        assert up == set(procs), f"not up after 60 s: {set(procs) - up}"
    finally:
        for pr in procs.values():
            if pr.poll() is None:
                pr.send_signal(signal.SIGINT)
        codes = {}
        for n, pr in procs.items():
            try:
                codes[n] = pr.wait(timeout=15)
            except subprocess.TimeoutExpired:
                pr.kill()
                codes[n] = "killed"
    assert codes == {"tracker": 0, "preprocessor": 0, "identifier": 0}, codes
