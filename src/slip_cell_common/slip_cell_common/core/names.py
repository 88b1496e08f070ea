# SPDX-License-Identifier: Apache-2.0
"""Topic, service, action and frame names of the cell: the one vocabulary (ROS-free).

Topic, service and action names are relative (resolved in the node's namespace, so a graph
can run under a namespace); `absolute` gives the form bags and ``ros2 bag`` show. Per-finger
names take the finger number (1 or 2). Frame names are without ``frames.tf_prefix``
(`slip_cell_common.core.frames.FrameParams.frame_id` adds it). YAML files keep their own
literal values.
"""
from __future__ import annotations

# ------------------------------------------------------------------ gripper (driver, simulator)
#: ``slip_msgs/GraspForceCommand``: grasp-force set-point for the force loop.
GRASP_FORCE_CMD = 'gripper/grasp_force_cmd'
#: ``slip_msgs/GripperStatus``: loop state, opening, measured force (500 Hz).
GRIPPER_STATUS = 'gripper/status'
#: ``slip_msgs/MotorCommand``: the voltage written to the actuator.
MOTOR_COMMAND = 'gripper/motor_command'
#: ``sensor_msgs/JointState`` of the finger joints.
GRIPPER_JOINT_STATES = 'gripper/joint_states'
#: ``slip_msgs/TransformArray`` of the fixed frames (latched).
STATIC_FRAMES = 'gripper/static_frames'
#: ``slip_msgs/TransformArray`` of the finger frames (moves with the opening).
FINGER_FRAMES = 'gripper/finger_frames'
#: ``std_srvs/Trigger`` services of the gripper.
GRIPPER_HOME_SRV = 'gripper/home'
GRIPPER_BIAS_FT_SRV = 'gripper/bias_ft'
GRIPPER_STOP_SRV = 'gripper/stop'
GRIPPER_ARM_SRV = 'gripper/arm'
#: ``control_msgs/action/GripperCommand`` (position = one finger joint [m], max_effort [N]).
GRIPPER_COMMAND_ACTION = 'gripper/gripper_cmd'
#: ``control_msgs/action/ParallelGripperCommand`` (same semantics, joint-state goal).
PARALLEL_GRIPPER_COMMAND_ACTION = 'gripper/parallel_gripper_cmd'


# ------------------------------------------------------------------ Net F/T, per finger
def ft_wrench(finger: int) -> str:
    """``geometry_msgs/WrenchStamped``: bias-removed wrench of finger ``finger`` [N, N·m]."""
    return f'finger_{finger}/ft/wrench'


def ft_raw(finger: int) -> str:
    """``geometry_msgs/WrenchStamped``: wrench before the bias is removed."""
    return f'finger_{finger}/ft/raw'


def ft_bias_srv(finger: int) -> str:
    """``std_srvs/Trigger``: bias one standalone Net F/T driver."""
    return f'finger_{finger}/ft/bias'


# ------------------------------------------------------------------ velocity sensors, per finger
def slip_base(finger: int) -> str:
    """Common prefix of one velocity sensor's topics and services."""
    return f'finger_{finger}/slip'


def slip_twist(finger: int) -> str:
    """``geometry_msgs/TwistStamped``: valid fused slip velocity [m/s, rad/s]."""
    return f'{slip_base(finger)}/twist'


def slip_state(finger: int) -> str:
    """``slip_msgs/PlanarSlip``: every sample with integrated pose and validity."""
    return f'{slip_base(finger)}/state'


def slip_chips(finger: int) -> str:
    """``slip_msgs/OpticalChipArray``: single-chip mode samples."""
    return f'{slip_base(finger)}/chips'


def slip_set_chip_mode_srv(finger: int) -> str:
    """``slip_msgs/SetChipMode`` service."""
    return f'{slip_base(finger)}/set_chip_mode'


def slip_reset_pose_srv(finger: int) -> str:
    """``std_srvs/Trigger``: reset the integrated pose."""
    return f'{slip_base(finger)}/reset_pose'


# ------------------------------------------------------------------ estimation and control
#: ``slip_msgs/ContactProperties`` (latched).
CONTACT_PROPERTIES = 'contact/properties'
CONTACT_START_SRV = 'contact/start'
CONTACT_GET_PROPERTIES_SRV = 'contact/get_properties'
#: ``slip_msgs/SlipTracking``.
SLIP_TRACKING = 'slip_control/tracking'
#: ``slip_msgs/SlipControllerState``.
SLIP_CONTROLLER_STATE = 'slip_control/state'
SLIP_SET_MODE_SRV = 'slip_control/set_mode'
SLIP_EXECUTE_ACTION = 'slip_control/execute'
EXPERIMENT_RUN_ACTION = 'experiment/run'

# ------------------------------------------------------------------ simulator only
SIM_STATE = 'sim/state'
SIM_OBJECT_POSE = 'sim/object_pose'
SIM_OBJECT_TWIST = 'sim/object_twist'
#: ``slip_msgs/ContactProperties``: the simulated truth (latched).
SIM_TRUE_CONTACT = 'sim/true_contact'
SIM_RESET_SRV = 'sim/reset'
SIM_RESET_SCENE_SRV = 'sim/reset_scene'
SIM_MOVE_GRIPPER_SRV = 'sim/move_gripper'
SIM_APPLY_DISTURBANCE_SRV = 'sim/apply_disturbance'
#: ``visualization_msgs/MarkerArray``: the simulated object and table (latched).
SIM_MARKERS = 'sim/markers'

# ------------------------------------------------------------------ display
#: ``visualization_msgs/MarkerArray``: pads, contact wrenches, slip velocities, slip target.
CELL_MARKERS = 'cell/markers'

# ------------------------------------------------------------------ ROS-wide (absolute)
DIAGNOSTICS = '/diagnostics'
#: ``rosgraph_msgs/Clock`` (the simulator publishes it under ``use_sim_time``).
CLOCK = '/clock'
TF = '/tf'
TF_STATIC = '/tf_static'
ROBOT_DESCRIPTION = 'robot_description'

# ------------------------------------------------------------------ frames (before tf_prefix)
#: The arm's flange; never prefixed.
TOOL0 = 'tool0'
GRIPPER_BASE_LINK = 'gripper_base_link'
#: Grasp frame: z from finger 1 to finger 2, objects slide in its xy plane.
GRIPPER_MIDDLE = 'gripper_middle'
#: Fixed world frame of the simulated cell (z up, REP-103); never prefixed, like ``tool0``.
WORLD = 'world'
#: The simulated object (its centre of mass), child of `WORLD`.
SIM_OBJECT = 'sim_object'


def ft_sensor_frame(finger: int) -> str:
    """Frame of finger ``finger``'s F/T sensor."""
    return f'ft_sensor_{finger}'


def vel_sensor_frame(finger: int) -> str:
    """Frame of finger ``finger``'s velocity sensor (pad surface, axes of the F/T sensor)."""
    return f'vel_sensor_{finger}'


def finger_joint(finger: int) -> str:
    """Prismatic joint of finger ``finger`` (before ``frames.tf_prefix``, like the frames)."""
    return f'finger_{finger}_joint'


def absolute(name: str) -> str:
    """``name`` as seen from the root namespace (``gripper/status`` → ``/gripper/status``)."""
    return name if name.startswith('/') else '/' + name
