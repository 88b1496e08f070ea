"""Launch descriptions built from the graph files of ``run_graph`` (full ROS installs only).

The launch files in ``share/slip_control/launch`` call `graph_launch_description`, so a graph
is described once (``config/*.graph.yaml``) for both ``run_graph`` and ``ros2 launch``.
Importing this module needs the ``launch`` and ``launch_ros`` packages of a full install.
"""
from __future__ import annotations

import os
from typing import Any

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _share(ref: str) -> str:
    package, _, rel = ref.partition('/')
    return os.path.join(get_package_share_directory(package), rel)


def _nodes(context: Any, graph_file: str) -> list[Node]:
    graph_path = os.path.join(get_package_share_directory('slip_bringup'), 'config', graph_file)
    with open(graph_path) as fh:
        graph = yaml.safe_load(fh)
    use_sim_time = LaunchConfiguration('use_sim_time').perform(context).lower() == 'true'
    extra = LaunchConfiguration('params_file').perform(context)
    prefix = LaunchConfiguration('tf_prefix').perform(context)
    actions = []
    for spec in graph['nodes']:
        params: list[Any] = [_share(ref) for ref in spec.get('params', [])]
        params.append({'use_sim_time': use_sim_time, 'frames.tf_prefix': prefix})
        if extra:
            params.append(extra)
        actions.append(Node(package=spec['package'], executable=spec['executable'],
                            name=spec['name'], namespace=LaunchConfiguration('namespace'),
                            parameters=params, output='screen', emulate_tty=True))
    return actions


def graph_launch_description(graph_file: str, use_sim_time: bool) -> LaunchDescription:
    """Launch description of a graph file, with namespace/tf_prefix/use_sim_time/params_file."""
    return LaunchDescription([
        DeclareLaunchArgument('namespace', default_value='', description='cell namespace'),
        DeclareLaunchArgument('tf_prefix', default_value='', description='frame id prefix'),
        DeclareLaunchArgument('use_sim_time', default_value=str(use_sim_time).lower(),
                              description='use /clock (the simulator publishes it)'),
        DeclareLaunchArgument('params_file', default_value='',
                              description='extra parameter file applied last'),
        OpaqueFunction(function=lambda context: _nodes(context, graph_file)),
    ])
