#!/usr/bin/env bash
# Print a lock of every pip-installed distribution of the venv (not `pip freeze`: the ROS wheels
# embed egg-info of non-installable names such as rclpy==7.1.5).
set -euo pipefail
"${1:?venv}/bin/python" - <<'PY'
import importlib.metadata as md
rows = {f"{d.metadata['Name']}=={d.version}" for d in md.distributions()
        if (d.read_text('INSTALLER') or '').strip() == 'pip'
        and d.metadata['Name'].lower() not in ('pip', 'setuptools')}
print('# Lock of every pip-installed distribution of the wheels venv (tools/lock.sh regenerates it).')
print('\n'.join(sorted(rows, key=str.lower)))
PY
