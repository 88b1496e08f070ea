"""ament_python package slip_gripper_driver."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'slip_gripper_driver'

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
            'gripper_driver = slip_gripper_driver.gripper_driver_node:main',
            'netft_driver = slip_gripper_driver.netft_driver_node:main',
            'gripper_firmware_emulator = slip_gripper_driver.core.firmware_emulator:main',
            'netft_emulator = slip_gripper_driver.core.netft_emulator:main',
            'force_tracking_test = slip_gripper_driver.force_tracking_test:main',
        ],
    },
)
