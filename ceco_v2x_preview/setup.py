from glob import glob

from setuptools import find_packages, setup

package_name = 'ceco_v2x_preview'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'tests']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    package_data={package_name: ['data/*', 'data/*/*']},
    include_package_data=True,
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='ceco maintainers',
    maintainer_email='maintainers@ceco.dev',
    description=(
        'V2X weather and traffic preview publisher and the scenario files (drive cycles, weather, occupant, '
        'comfort bounds) for ceco.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'preview_node = ceco_v2x_preview.entry_points:preview_node',
        ],
    },
)
