# SPDX-License-Identifier: Apache-2.0
"""Resolve file parameters the way ROS users write them (needs the ament index, not rclpy).

* ``/abs/path.yaml``: used as is.
* ``package://<package>/<relative path>``: relative to that package's share directory
  (``package://slip_velocity_sensor/config/calibration_sensor_1.yaml``).
* ``relative/path.yaml``: relative to this package's share directory
  (``config/calibration_sensor_1.yaml`` = the installed calibration files).
* ``~/...``: the user's home directory.
"""
from __future__ import annotations

from pathlib import Path

PACKAGE = 'slip_velocity_sensor'
_SCHEME = 'package://'


class ResourceError(ValueError):
    """A file parameter cannot be resolved; the message names the parameter value."""


def share_directory(package: str = PACKAGE) -> Path:
    """Installed share directory of ``package``.

    Raises:
        ResourceError: The package is not in the ament index (workspace not sourced?).
    """
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        return Path(get_package_share_directory(package))
    except (PackageNotFoundError, LookupError, ValueError) as exc:
        raise ResourceError(f'package {package!r} not found in the ament index '
                            f'(is install/setup.bash sourced?): {exc}') from exc


def resolve_path(value: str, package: str = PACKAGE) -> str:
    """The absolute path a file parameter refers to ('' stays '').

    Args:
        value: Parameter value (see the module docstring for the accepted forms).
        package: Package whose share directory relative paths refer to.

    Raises:
        ResourceError: Malformed ``package://`` URL or unknown package.
    """
    if not value:
        return ''
    if value.startswith(_SCHEME):
        pkg, _, rel = value[len(_SCHEME):].partition('/')
        if not pkg or not rel:
            raise ResourceError(f'{value!r}: expected package://<package>/<path>')
        return str(share_directory(pkg) / rel)
    path = Path(value).expanduser()
    if path.is_absolute():
        return str(path)
    return str(share_directory(package) / path)
