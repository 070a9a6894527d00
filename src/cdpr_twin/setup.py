from setuptools import find_packages, setup

package_name = 'cdpr_twin'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools', 'numpy'],
    # colcon test runs pytest for a package that names it here
    extras_require={'test': ['pytest']},
    zip_safe=True,
    maintainer='cdpr maintainers',
    maintainer_email='cdpr-maintainers@example.org',
    description='The digital twin (healthy rigid model with its own controller) and the plant simulator with failure injection.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'digital_twin = cdpr_twin.nodes.digital_twin_node:main',
            'plant_simulator = cdpr_twin.nodes.plant_simulator_node:main',
            'ros2_control_bridge = cdpr_twin.nodes.ros2_control_bridge_node:main',
        ],
    },
)
