"""ament_python package friction_models."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'friction_models'

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
            'sim_gripper = friction_models.sim_gripper_node:main',
            'friction_models_cli = friction_models.cli:main',
        ],
    },
)
