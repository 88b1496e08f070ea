"""Launch the hardware gripper cell on a full ROS 2 Jazzy install.

The same graph as `run_graph --hardware` (config/hardware_cell.graph.yaml), with the same
parameter files.
Arguments: namespace, tf_prefix, use_sim_time, params_file (an extra YAML applied after the
packages' own files, for site-specific ports, addresses and gains).

    ros2 launch slip_bringup cell.launch.py namespace:=cell_a
"""
from slip_bringup.launch_graph import graph_launch_description


def generate_launch_description():
    return graph_launch_description('hardware_cell.graph.yaml', use_sim_time=False)
