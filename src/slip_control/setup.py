"""ament_python package slip_control."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'slip_control'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Slip cell maintainers',
    maintainer_email='maintainers@slip-cell.invalid',
    description=open('package.xml').read().split('<description>')[1].split('</description>')[0],
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'contact_estimator = slip_control.contact_estimator_node:main',
            'slip_controller = slip_control.slip_controller_node:main',
            'experiment_runner = slip_control.experiment_runner_node:main',
        ],
    },
)
