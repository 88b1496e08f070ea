"""Launch the gripper driver alone on a full ROS 2 Jazzy install (syntax-checked here).

Uses the same parameter files as ``run_graph``: the shared ``cell.yaml`` (frames), the
package's ``gripper_driver.yaml``, then an optional site file (serial port, box addresses).

    ros2 launch slip_gripper_driver gripper_driver.launch.py params_file:=/etc/slip/site.yaml
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _nodes(context):
    share = get_package_share_directory('slip_gripper_driver')
    params = [os.path.join(share, 'config', 'cell.yaml'),
              os.path.join(share, 'config', 'gripper_driver.yaml'),
              {'use_sim_time': LaunchConfiguration('use_sim_time').perform(context) == 'true',
               'frames.tf_prefix': LaunchConfiguration('tf_prefix').perform(context)}]
    extra = LaunchConfiguration('params_file').perform(context)
    if extra:
        params.append(extra)
    return [Node(package='slip_gripper_driver', executable='gripper_driver',
                 name='gripper_driver', namespace=LaunchConfiguration('namespace'),
                 parameters=params, output='screen', emulate_tty=True)]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('namespace', default_value='', description='cell namespace'),
        DeclareLaunchArgument('tf_prefix', default_value='', description='frame id prefix'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='use /clock'),
        DeclareLaunchArgument('params_file', default_value='',
                              description='site parameter file applied last (serial.port, '
                                          'ft.finger_k.address)'),
        OpaqueFunction(function=_nodes),
    ])
