"""The paper's failure scenario through the node graph, as `make demo` runs it: the circle,
cable 4 breaking at 3/8 of the move (nearest its exit point), lockstep, on the elastic
plant with the calibrated thresholds: `ros2 launch cdpr_bringup cdpr_demo.launch.py`.
It records every topic into runs/demo_launch/<UTC time>/bag (or bag:=FOLDER) and ends by
printing how the run went, as `make demo` does. Any argument of cdpr.launch.py may be
given as well."""
import time
from pathlib import Path

from launch import LaunchDescription
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration

DEMO = {'motion': 'circle', 'fail_cable': '4', 'fail_at_fraction': '0.375', 'clock': 'lockstep'}
BAG_FOLDER = 'runs/demo_launch'


def generate_launch_description():
    graph = Path(__file__).with_name('cdpr.launch.py')
    bag = LaunchConfiguration('bag', default=f'{BAG_FOLDER}/{time.strftime("%Y%m%d-%H%M%S", time.gmtime())}/bag')
    return LaunchDescription([IncludeLaunchDescription(
        PythonLaunchDescriptionSource(str(graph)), launch_arguments=[*DEMO.items(), ('bag', bag)])])
