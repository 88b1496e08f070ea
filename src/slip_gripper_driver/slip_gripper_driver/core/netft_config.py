# SPDX-License-Identifier: Apache-2.0
"""The box's ``netftapi2.xml``: scale, range, RDT rate and settings (ROS-free, HW-7)."""
from __future__ import annotations

import math
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

from slip_gripper_driver.core.ft_scale import (ForceTorqueScale, force_unit_factor,
                                               torque_unit_factor)
from slip_gripper_driver.core.ft_validity import RangeLimits
from slip_gripper_driver.core.netft_client import NetFTError

#: HTTP port of ``netftapi2.xml`` unless the box was set up otherwise.
HTTP_PORT = 80


@dataclass(frozen=True)
class NetFTConfig:
    """What the driver needs from ``netftapi2.xml``.

    Attributes:
        scale: Counts per unit and units.
        rdt_rate_hz: ``comrdtrate`` [Hz]; NaN if absent.
        rdt_enabled: ``comrdte``; None if absent.
        values: Every tag with its raw text (``runstat``, ``setbias``, ``cfgmr``, ``netip``…).
        measuring_range: ``cfgmr`` in SI (|Fx|, |Fy|, |Fz| [N], |Tx|, |Ty|, |Tz| [N·m]);
            None if absent or malformed.
    """

    scale: ForceTorqueScale
    rdt_rate_hz: float
    rdt_enabled: bool | None
    values: dict[str, str] = field(default_factory=dict)
    measuring_range: RangeLimits | None = None


def parse_measuring_range(text: str, scale: ForceTorqueScale) -> RangeLimits | None:
    """``cfgmr`` (``'40;40;120;2;2;2'`` in the box's units) in N and N·m; None if not six
    finite non-negative numbers."""
    try:
        values = [float(v) for v in text.replace(',', ';').split(';') if v.strip()]
    except ValueError:
        return None
    if len(values) != 6 or not all(math.isfinite(v) and v >= 0.0 for v in values):
        return None
    f = force_unit_factor(scale.force_unit)
    m = torque_unit_factor(scale.torque_unit)
    return (values[0] * f, values[1] * f, values[2] * f, values[3] * m, values[4] * m,
            values[5] * m)


def parse_netft_config(xml_text: str | bytes) -> NetFTConfig:
    """Parse the box's ``netftapi2.xml``.

    Raises:
        ValueError: Not XML, or ``cfgcpf``/``cfgcpt``/``scfgfu``/``scfgtu`` missing or invalid.
    """
    try:
        root = ET.fromstring(xml_text)
    except ET.ParseError as exc:
        raise ValueError(f'netftapi2.xml is not valid XML: {exc}') from exc
    values = {child.tag.strip().lower(): (child.text or '').strip() for child in root.iter()
              if child is not root}
    missing = [k for k in ('cfgcpf', 'cfgcpt', 'scfgfu', 'scfgtu') if not values.get(k)]
    if missing:
        raise ValueError(f'netftapi2.xml lacks {", ".join(missing)}')
    try:
        cpf = float(values['cfgcpf'])
        cpt = float(values['cfgcpt'])
    except ValueError as exc:
        raise ValueError(f'netftapi2.xml counts per unit not numeric: {exc}') from exc
    scale = ForceTorqueScale(cpf, cpt, values['scfgfu'], values['scfgtu'])
    try:
        rate = float(values.get('comrdtrate', 'nan'))
    except ValueError:
        rate = math.nan
    enabled_text = values.get('comrdte', '').lower()
    enabled = {'true': True, '1': True, 'false': False, '0': False}.get(enabled_text)
    return NetFTConfig(scale, rate, enabled, values,
                       parse_measuring_range(values.get('cfgmr', ''), scale))


def fetch_netft_config(address: str, *, http_port: int = HTTP_PORT,
                       timeout_s: float = 2.0) -> NetFTConfig:
    """Download and parse ``http://<address>:<http_port>/netftapi2.xml``.

    Raises:
        NetFTError: Unreachable box or invalid document (the message names the address).
    """
    url = f'http://{address}:{http_port}/netftapi2.xml'
    try:
        with urllib.request.urlopen(url, timeout=timeout_s) as response:
            body = response.read()
    except (urllib.error.URLError, OSError) as exc:
        raise NetFTError(f'cannot read {url}: {exc}') from exc
    try:
        return parse_netft_config(body)
    except ValueError as exc:
        raise NetFTError(f'{url}: {exc}') from exc

