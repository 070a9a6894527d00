"""The paper's failure scenario through the node graph, as `make demo` runs it: the circle,
cable 4 breaking at 3/8 of the move (nearest its exit point), lockstep, on the elastic
plant with the calibrated thresholds: `ros2 launch cdpr_bringup cdpr_demo.launch.py`.
Any argument of cdpr.launch.py may be given as well (e.g. bag:=runs/demo/bag)."""
from pathlib import Path

from launch import LaunchDescription
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource

DEMO = {'motion': 'circle', 'fail_cable': '4', 'fail_at_fraction': '0.375', 'clock': 'lockstep'}


def generate_launch_description():
    graph = Path(__file__).with_name('cdpr.launch.py')
    return LaunchDescription([IncludeLaunchDescription(
        PythonLaunchDescriptionSource(str(graph)), launch_arguments=DEMO.items())])
