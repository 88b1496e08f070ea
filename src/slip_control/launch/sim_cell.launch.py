"""Launch the simulated gripper cell on a full ROS 2 Jazzy install.

Describes the same graph as `run_graph --sim` (config/sim_cell.graph.yaml), with the same
parameter files. Arguments: namespace, tf_prefix, use_sim_time, params_file (an extra YAML
applied after the packages' own files, for site-specific ports, addresses and gains).

    ros2 launch slip_control sim_cell.launch.py namespace:=cell_a
"""
import os

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

GRAPH = 'sim_cell.graph.yaml'
SIM = True


def _share(ref):
    package, _, rel = ref.partition('/')
    return os.path.join(get_package_share_directory(package), rel)


def _nodes(context):
    graph_path = os.path.join(get_package_share_directory('slip_control'), 'config', GRAPH)
    with open(graph_path) as fh:
        graph = yaml.safe_load(fh)
    use_sim_time = LaunchConfiguration('use_sim_time').perform(context).lower() == 'true'
    extra = LaunchConfiguration('params_file').perform(context)
    prefix = LaunchConfiguration('tf_prefix').perform(context)
    actions = []
    for spec in graph['nodes']:
        params = [_share(ref) for ref in spec.get('params', [])]
        params.append({'use_sim_time': use_sim_time, 'frames.tf_prefix': prefix})
        if extra:
            params.append(extra)
        actions.append(Node(package=spec['package'], executable=spec['executable'],
                            name=spec['name'], namespace=LaunchConfiguration('namespace'),
                            parameters=params, output='screen', emulate_tty=True))
    return actions


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('namespace', default_value='', description='cell namespace'),
        DeclareLaunchArgument('tf_prefix', default_value='', description='frame id prefix'),
        DeclareLaunchArgument('use_sim_time', default_value=str(SIM).lower(),
                              description='use /clock (the simulator publishes it)'),
        DeclareLaunchArgument('params_file', default_value='',
                              description='extra parameter file applied last'),
        OpaqueFunction(function=_nodes),
    ])
