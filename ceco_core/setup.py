from setuptools import find_packages, setup

package_name = 'ceco_core'

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
        'Pure shared core of ceco (no ROS): units, psychrometrics, the numeric/CasADi maths backend, '
        'ISO 7730 comfort, scenario types, controller contracts, the production climate law, metrics '
        'and the run-directory format.'
    ),
    license='Apache-2.0',
)
