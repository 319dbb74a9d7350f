from setuptools import find_packages, setup

package_name = 'ceco_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='ceco maintainers',
    maintainer_email='maintainers@ceco.dev',
    description=(
        'ROS 2 glue shared by the ceco nodes: topic names, QoS profiles, parameter declaration, message '
        'conversions in both directions, node main.'
    ),
    license='Apache-2.0',
)
