from glob import glob

from setuptools import find_packages, setup

package_name = 'ceco_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py') + glob('launch/*.launch.xml')),
    ],
    package_data={package_name: ['data/*', 'data/*/*', 'data/*/*/*']},
    include_package_data=True,
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='ceco maintainers',
    maintainer_email='maintainers@ceco.dev',
    description=(
        'The ceco command: runs the node stack as supervised processes, records rosbag2 bags, replays them, '
        'reports energy and comfort.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'ceco = ceco_bringup.cli:main',
        ],
    },
)
