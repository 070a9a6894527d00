from setuptools import find_packages, setup

package_name = 'cdpr_control'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    # the paper's settings every robot file falls back on (config.py)
    package_data={package_name: ['defaults/*.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools', 'numpy', 'PyYAML'],
    # colcon test runs pytest for a package that names it here
    extras_require={'test': ['pytest']},
    zip_safe=True,
    maintainer='cdpr maintainers',
    maintainer_email='cdpr-maintainers@example.org',
    description='Cable robot model (kinematics, tension distribution, dynamics), trajectories and the PD + feed-forward controller.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'trajectory_generator = cdpr_control.control.trajectory_generator_node:main',
            'controller = cdpr_control.control.controller_node:main',
        ],
    },
)
