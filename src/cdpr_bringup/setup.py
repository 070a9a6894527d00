from glob import glob

from setuptools import find_packages, setup

package_name = 'cdpr_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml') + glob('config/*.rviz')),
        ('share/' + package_name + '/config/robots', glob('config/robots/*.yaml')),
        ('share/' + package_name + '/config/params', glob('config/params/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools', 'numpy', 'PyYAML', 'matplotlib', 'rosbags', 'mcap',
                      'distributed'],
    # colcon test runs pytest for a package that names it here
    extras_require={'test': ['pytest']},
    zip_safe=True,
    maintainer='cdpr maintainers',
    maintainer_email='cdpr-maintainers@example.org',
    description='Robot and scenario configs, the scripts that start the cdpr graph, bag recording, scenario runner, reports and benchmarks.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'cdpr-robot = cdpr_bringup.reports.robot_summary:main',
            'cdpr-bench = cdpr_bringup.bench.main:main',
            'cdpr-graph = cdpr_bringup.graph.launcher:main',
            'cdpr-scenario = cdpr_bringup.scenario.command:main',
            'cdpr-calibrate = cdpr_bringup.campaigns.calibrate:main',
            'cdpr-identify = cdpr_bringup.reports.identify:main',
            'cdpr-fdi-offline = cdpr_bringup.reports.fdi_offline:main',
            'cdpr-campaign = cdpr_bringup.campaigns.campaign:main',
            'cdpr-report = cdpr_bringup.reports.report:main',
            'cdpr-params = cdpr_bringup.graph.params_files:main',
            'bag_recorder = cdpr_bringup.bags.recorder_node:main',
            'composed_loop = cdpr_bringup.graph.composed_loop:main',
        ],
    },
)
