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
            'slip_bag = slip_control.bag_cli:main',
            'bag_recorder = slip_control.bag_nodes:recorder_main',
            'bag_replay = slip_control.bag_nodes:replay_main',
            'run_graph = slip_control.run_graph:main',
            'slip_cli = slip_control.slip_cli:main',
            'slip_analyze = slip_control.analyze:main',
            'slip_demo = slip_control.demo:main',
            'slip_evaluate = slip_control.evaluate_cli:main',
            'contact_estimator = slip_control.contact_estimator_node:main',
            'slip_controller = slip_control.slip_controller_node:main',
            'experiment_runner = slip_control.experiment_runner_node:main',
        ],
    },
)
