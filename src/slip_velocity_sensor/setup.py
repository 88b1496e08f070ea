"""ament_python package slip_velocity_sensor."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'slip_velocity_sensor'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
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
            'velocity_sensor = slip_velocity_sensor.velocity_sensor_node:main',
            'velocity_sensor_emulator = slip_velocity_sensor.core.emulator:main',
            'calibration_fit = slip_velocity_sensor.calibration_fit:main',
            'calibration_recorder = slip_velocity_sensor.calibration_recorder:main',
        ],
    },
)
