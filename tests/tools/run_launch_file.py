"""Run a launch file with the `launch` package, as `ros2 launch` does once it has parsed
its command line: run_launch_file.py FILE [name:=value ...]; exits with launch's code."""
import sys

from launch import LaunchDescription, LaunchService
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource

path, *pairs = sys.argv[1:]
service = LaunchService()
service.include_launch_description(LaunchDescription([IncludeLaunchDescription(
    PythonLaunchDescriptionSource(path),
    launch_arguments=[tuple(pair.split(':=', 1)) for pair in pairs])]))
sys.exit(service.run())
