"""ament_python package slip_bringup."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'slip_bringup'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
        # Wrappers of the user tools in <prefix>/bin: colcon puts that directory on PATH.
        ('bin', sorted(glob('bin/*'))),
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
            'slip_bag = slip_bringup.bag_cli:main',
            'bag_recorder = slip_bringup.bag_nodes:recorder_main',
            'bag_replay = slip_bringup.bag_nodes:replay_main',
            'run_graph = slip_bringup.run_graph:main',
            'slip_cli = slip_bringup.slip_cli:main',
            'slip_analyze = slip_bringup.analyze:main',
            'slip_demo = slip_bringup.demo:main',
            'slip_evaluate = slip_bringup.evaluate_cli:main',
            'foxglove_live = slip_bringup.foxglove_live:main',
            'cell_markers = slip_bringup.cell_markers_node:main',
        ],
    },
)
