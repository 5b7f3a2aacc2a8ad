"""tail_beam: one ament_python package holding tail_beam_sim and tail_beam_id."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "tail_beam"
ROS_WHEELS = [
    "ros-rclpy",
    "ros-std-msgs",
    "ros-sensor-msgs",
    "ros-geometry-msgs",
    "ros-rosgraph-msgs",
    "ros-rmw-fastrtps-cpp",
]

setup(
    name=PACKAGE,
    version="0.1.0",
    description=(
        "Emulated instrumented tail beam of a top-coal-caving support, "
        "with coal-gangue identification"
    ),
    packages=find_packages(
        include=["tail_beam_sim", "tail_beam_sim.*", "tail_beam_id", "tail_beam_id.*"]
    ),
    package_data={"tail_beam_id": ["models/*.json"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", sorted(glob("config/*.yaml"))),
    ],
    python_requires=">=3.10",
    install_requires=["numpy>=1.24", "scipy>=1.10", "rosbags>=0.10", "PyYAML>=6"],
    extras_require={
        "ros": ROS_WHEELS,
        "plot": ["matplotlib>=3.7"],
        "test": [
            "pytest>=8",
            "pytest-xdist>=3",
            "mcap>=1.1",
            "mcap-ros2-support>=0.5",
            "ruff>=0.6",
        ],
        "colcon": [
            "colcon-core",
            "colcon-ros",
            "colcon-python-setup-py",
            "colcon-package-selection",
            "colcon-recursive-crawl",
            "colcon-library-path",
            "colcon-bash",
            "ros-ament-package",
            "setuptools<80",
        ],
    },
    zip_safe=False,
    entry_points={
        "console_scripts": [
            # Through start.py: a stop signal during the imports ends the process quietly.
            "sim_node = tail_beam_sim.ros.start:sim_node",
            "id_node = tail_beam_id.ros.start:id_node",
            "caving_node = tail_beam_id.ros.start:caving_node",
            "face_host = tail_beam_id.ros.start:face_host",
            "bag_recorder = tail_beam_sim.ros.start:bag_recorder",
            "bag_replay = tail_beam_sim.ros.start:bag_replay",
            "tail-beam = tail_beam_sim.cli:main",
        ],
        # The verbs of ``tail-beam``: each package contributes its own (as ros2cli and colcon do),
        # so the simulator's command line never names the identifier.
        "tail_beam.verbs": [
            "simulate = tail_beam_sim.cli.simulate_cmd:register",
            "sweep = tail_beam_sim.cli.sweep_cmd:register",
            "send = tail_beam_sim.cli.send_cmd:register",
            "bag = tail_beam_sim.cli.bag_cmd:register",
            "bench = tail_beam_sim.cli.bench_cmd:register",
            "identify = tail_beam_id.cli.identify_cmd:register",
            "evaluate = tail_beam_id.cli.evaluate_cmd:register",
            "demo = tail_beam_id.cli.demo_cmd:register",
            "calibrate = tail_beam_id.cli.calibrate_cmd:register",
            "caving = tail_beam_id.cli.caving_cmd:register",
        ],
    },
)
