"""Launch two standalone Net F/T drivers on a full ROS 2 Jazzy install (syntax-checked here).

For ``gripper_driver`` with ``ft.mode: topic``: ``netft_driver_1`` and ``netft_driver_2`` own the
boxes and publish ``finger_k/ft/wrench``. Never run them while the gripper driver's embedded
clients use the same boxes (a box serves one RDT client).

    ros2 launch slip_gripper_driver netft_driver.launch.py address_1:=192.168.56.6
"""
import os

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _nodes(context):
    share = get_package_share_directory('slip_gripper_driver')
    with open(os.path.join(share, 'config', 'netft_driver.yaml')) as fh:
        # The file is keyed by the default node name; pass its values to both instances.
        defaults = yaml.safe_load(fh)['netft_driver']['ros__parameters']
    extra = LaunchConfiguration('params_file').perform(context)
    nodes = []
    for finger in (1, 2):
        params = [defaults, {'finger': finger, 'address': LaunchConfiguration(
            f'address_{finger}').perform(context)}]
        if extra:
            params.append(extra)
        nodes.append(Node(package='slip_gripper_driver', executable='netft_driver',
                          name=f'netft_driver_{finger}',
                          namespace=LaunchConfiguration('namespace'), parameters=params,
                          output='screen', emulate_tty=True))
    return nodes


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('namespace', default_value='', description='cell namespace'),
        DeclareLaunchArgument('address_1', default_value='192.168.56.6',
                              description='Net F/T box of finger 1'),
        DeclareLaunchArgument('address_2', default_value='192.168.56.5',
                              description='Net F/T box of finger 2'),
        DeclareLaunchArgument('params_file', default_value='',
                              description='extra parameter file applied last'),
        OpaqueFunction(function=_nodes),
    ])
