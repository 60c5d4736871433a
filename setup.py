"""ament_python package rig_identification (also installable with pip)."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "rig_identification"

NODES = {
    "sensor_driver": "rig_identification.nodes.sensor_driver:main",
    "tracker": "rig_identification.nodes.tracker_node:main",
    "preprocessor": "rig_identification.nodes.preprocessor_node:main",
    "identifier": "rig_identification.nodes.identifier_node:main",
    "mass_properties_client": "rig_identification.nodes.client:main",
    "recorder": "rig_identification.nodes.recorder:main",
    "rig_visualizer": "rig_identification.nodes.visualizer:main",
    "demo": "rig_identification.nodes.demo:main",
}

setup(
    name=PACKAGE,
    version="0.1.0",
    # data/ holds files, not modules: named here so that setuptools ships it without a warning
    packages=find_packages(exclude=["test", "test.*", "bench"]) + [f"{PACKAGE}.data"],
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config/cases", sorted(glob("config/cases/*.yaml"))),
        (f"share/{PACKAGE}/config/rigs", sorted(glob("config/rigs/*.yaml"))),
        (f"share/{PACKAGE}/config/params", sorted(glob("config/params/*.yaml"))),
        (f"share/{PACKAGE}/config/dds", sorted(glob("config/dds/*.xml"))),
        (f"share/{PACKAGE}/launch", sorted(glob("launch/*.launch.py"))),
    ],
    package_data={PACKAGE: ["data/*.yaml", "data/*.csv"]},
    include_package_data=True,
    install_requires=["setuptools", "numpy", "scipy", "numba", "threadpoolctl", "pyyaml", "rosbags"],
    zip_safe=True,
    maintainer="rig_identification developers",
    maintainer_email="dev@rig-identification.local",
    description="Mass, centre of gravity and inertia tensor of a vehicle on a cable-suspended rig",
    license="Apache-2.0",
    extras_require={"test": ["pytest"]},
    entry_points={
        "console_scripts": [f"{k} = {v}" for k, v in NODES.items()]
        + ["rig-identify = rig_identification.cli.main:identify_main", "rig-sim = rig_identification.cli.main:sim_main",
           "rig-record = rig_identification.nodes.recorder:record_main"],
    },
)
