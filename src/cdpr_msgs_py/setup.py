from setuptools import find_packages, setup

package_name = 'cdpr_msgs_py'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['fastdds_loopback.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml', package_name + '/fastdds_loopback.xml']),
    ],
    install_requires=['setuptools', 'numpy'],
    # colcon test runs pytest for a package that names it here
    extras_require={'test': ['pytest']},
    zip_safe=True,
    maintainer='cdpr maintainers',
    maintainer_email='cdpr-maintainers@example.org',
    description='The cdpr interface contract in Python: topic names, QoS profiles, mode names, message <-> numpy conversions and validation.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [],
    },
)
