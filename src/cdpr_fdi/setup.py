from setuptools import find_packages, setup

package_name = 'cdpr_fdi'

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
    description='Sensorless cable-failure detection and identification, safe points and recovery planning.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'supervisor = cdpr_fdi.nodes.supervisor_node:main',
            'markers = cdpr_fdi.nodes.markers_node:main',
        ],
    },
)
