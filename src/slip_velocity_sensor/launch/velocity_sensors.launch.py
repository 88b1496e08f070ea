# SPDX-License-Identifier: Apache-2.0
"""Both finger velocity sensors (full ROS installs; here run_graph uses the same YAML files).

    ros2 launch slip_velocity_sensor velocity_sensors.launch.py \\
        port_1:=/dev/serial/by-id/...-if00-port0 port_2:=/dev/serial/by-id/...-if00-port0

The nodes autostart (configure + activate) through their ``autostart`` parameter.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode


def generate_launch_description() -> LaunchDescription:
    share = get_package_share_directory('slip_velocity_sensor')
    args = [DeclareLaunchArgument('namespace', default_value=''),
            DeclareLaunchArgument('use_sim_time', default_value='false')]
    nodes = []
    for k in (1, 2):
        args.append(DeclareLaunchArgument(f'port_{k}', description=f'serial port of sensor_{k}'))
        nodes.append(LifecycleNode(
            package='slip_velocity_sensor', executable='velocity_sensor',
            name=f'velocity_sensor_{k}', namespace=LaunchConfiguration('namespace'),
            output='screen',
            parameters=[os.path.join(share, 'config', f'velocity_sensor_{k}.yaml'),
                        {'port': LaunchConfiguration(f'port_{k}'),
                         'use_sim_time': LaunchConfiguration('use_sim_time')}]))
    return LaunchDescription(args + nodes)
