from glob import glob

from setuptools import find_packages, setup

package_name = 'ceco_controller'

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
    description='CECO nonlinear MPC strategies (CasADi) and the baseline PI climate controller for ceco.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'mpc_node = ceco_controller.entry_points:mpc_node',
            'baseline_node = ceco_controller.entry_points:baseline_node',
        ],
    },
)
