# SPDX-License-Identifier: Apache-2.0
"""Contact surfaces: the cell grid and normalised pressure maps (spec §1, §3; thesis §2.2).

Grid: ``nx × ny`` square cells of side ``h``; column ``i`` has centre
``x_i = (i + ½ − nx/2)·h`` and row ``j`` has centre ``y_j = −(j + ½ − ny/2)·h`` (row 0 is the
top, +y). Arrays are indexed ``[j, i]`` (image order) everywhere; other layouts are converted in
:meth:`ContactSurface.from_array` only.

A pressure map ``p_ij ≥ 0`` of any scale is normalised once, ``p̂ = p/Σp``; the per-cell normal
force is ``f_n·p̂_ij``. Derived quantities (ρ = cell centre relative to the pad centre):

* centre of pressure ``c = Σ p̂ ρ``;
* characteristic radius (one point per cell) ``r_a = Σ p̂ ‖ρ − c‖`` (spec §6.1) -- the
  reference's bilinear value is :func:`friction_models.core.limit_surface.characteristic_radius`;
* second moment about the CoP ``J_c = Σ p̂ ‖ρ − c‖²`` [m²] (viscous torque, spec §6.3, §13.8).

Canonical shapes (spec §3 table) are built by :func:`standard_surface` and the named
constructors; a 20 mm patch on a 21 × 21 grid unless stated.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    'STANDARD_SURFACES',
    'ContactSurface',
    'circle',
    'line',
    'line_grad',
    'line_grad_x',
    'non_convex_1',
    'non_convex_2',
    'soft_finger',
    'square',
    'standard_surface',
]

Layout = Literal['ji', 'ij', 'flat']

#: Names accepted by :func:`standard_surface` (spec §3; the C++ CamelCase names also work).
STANDARD_SURFACES: tuple[str, ...] = (
    'square', 'circle', 'line', 'line_grad', 'line_grad_x', 'non_convex_1', 'non_convex_2')


def _readonly(a: NDArray[np.float64]) -> NDArray[np.float64]:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class ContactSurface:
    """An immutable contact patch: grid geometry plus a normalised pressure map.

    Construct with :meth:`from_array`, :meth:`from_mask` or the named shape functions.

    Attributes:
        pressure: Normalised pressure ``p̂`` [-], shape (ny, nx), sums to 1, read-only.
        cell_size: Cell side ``h`` [m].
        name: Label used in reports and cache files.
        scale: Multiplier such that the map as given equals ``scale·p̂`` (``Σp``); when the map
            was a pressure in Pa, ``scale·h²`` is the total normal force [N].
        active: Flat ``[j, i]`` indices of the cells with ``p̂ > 0`` (read-only).
        x: Cell-centre x of the active cells [m] (read-only).
        y: Cell-centre y of the active cells [m] (read-only).
        weights: ``p̂`` of the active cells [-] (read-only).
        cop: Centre of pressure ``c = Σ p̂ ρ`` [m].
        r_a_cells: One-point characteristic radius ``Σ p̂ ‖ρ − c‖`` [m] (spec §6.1).
        second_moment: ``J_c = Σ p̂ ‖ρ − c‖²`` about the CoP [m²] (spec §6.3).
        polar_moment: ``Σ p̂ ‖ρ‖²`` about the pad centre [m²].
    """

    pressure: NDArray[np.float64]
    cell_size: float
    name: str = 'custom'
    scale: float = 1.0
    # Derived, filled in __post_init__ (all read-only arrays over the *active* cells p̂ > 0).
    active: NDArray[np.intp] = field(init=False, repr=False)
    x: NDArray[np.float64] = field(init=False, repr=False)
    y: NDArray[np.float64] = field(init=False, repr=False)
    weights: NDArray[np.float64] = field(init=False, repr=False)
    cop: tuple[float, float] = field(init=False)
    r_a_cells: float = field(init=False)
    second_moment: float = field(init=False)
    polar_moment: float = field(init=False)

    def __post_init__(self) -> None:
        """Validate the map and precompute the active-cell geometry and moments."""
        p = np.array(self.pressure, dtype=np.float64, copy=True)
        if p.ndim != 2 or p.shape[0] < 1 or p.shape[1] < 1:
            raise ValueError(f'pressure map must be 2-D (ny, nx), got shape {p.shape}')
        if not np.all(np.isfinite(p)) or np.any(p < 0.0):
            raise ValueError('pressure map must be finite and non-negative')
        total = float(p.sum())
        if total <= 0.0:
            raise ValueError('pressure map has no contact (all cells zero)')
        if not (math.isfinite(self.cell_size) and self.cell_size > 0.0):
            raise ValueError(f'cell_size must be a positive length in m, got {self.cell_size!r}')
        # An already normalised map is kept bit for bit, so scaled copies hash identically.
        if abs(total - 1.0) > 1e-12:
            p /= total
        ny, nx = p.shape
        h = float(self.cell_size)
        xs = (np.arange(nx) + 0.5 - nx / 2.0) * h
        ys = -(np.arange(ny) + 0.5 - ny / 2.0) * h
        active = np.flatnonzero(p.ravel())
        jj, ii = np.divmod(active, nx)
        x = xs[ii]
        y = ys[jj]
        w = p.ravel()[active]
        cx = float(w @ x)
        cy = float(w @ y)
        dx = x - cx
        dy = y - cy
        d2 = dx * dx + dy * dy
        setattr_ = object.__setattr__
        setattr_(self, 'pressure', _readonly(p))
        setattr_(self, 'cell_size', h)
        setattr_(self, 'scale', float(self.scale) * total)
        setattr_(self, 'active', active.astype(np.intp))
        self.active.setflags(write=False)
        setattr_(self, 'x', _readonly(x))
        setattr_(self, 'y', _readonly(y))
        setattr_(self, 'weights', _readonly(w))
        setattr_(self, 'cop', (cx, cy))
        setattr_(self, 'r_a_cells', float(w @ np.sqrt(d2)))
        setattr_(self, 'second_moment', float(w @ d2))
        setattr_(self, 'polar_moment', float(w @ (x * x + y * y)))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_array(cls, pressure: ArrayLike, cell_size: float, name: str = 'custom',
                   layout: Layout = 'ji', shape: tuple[int, int] | None = None,
                   ) -> ContactSurface:
        """Build a surface from a pressure array of any scale.

        Args:
            pressure: Non-negative pressure values (relative, or in Pa).
            cell_size: Cell side ``h`` [m].
            name: Label.
            layout: ``'ji'`` -- image order ``[row j (top = +y), column i (+x)]`` (ours);
                ``'ij'`` -- ``[i][j]`` as in the C++ port (transposed);
                ``'flat'`` -- flat with ``i`` fastest, ``index = i + j·nx`` (needs ``shape``).
            shape: ``(ny, nx)`` for the flat layout.

        Returns:
            The surface.
        """
        a = np.asarray(pressure, dtype=np.float64)
        if layout == 'ij':
            a = a.T
        elif layout == 'flat':
            if shape is None:
                raise ValueError("layout='flat' needs shape=(ny, nx)")
            a = a.reshape(shape)
        elif layout != 'ji':
            raise ValueError(f"layout must be 'ji', 'ij' or 'flat', got {layout!r}")
        return cls(pressure=a, cell_size=cell_size, name=name)

    @classmethod
    def from_mask(cls, mask: ArrayLike, cell_size: float, name: str = 'mask') -> ContactSurface:
        """Uniform pressure on the True cells of a boolean ``[j, i]`` mask (any shape)."""
        m = np.asarray(mask, dtype=bool)
        return cls(pressure=m.astype(np.float64), cell_size=cell_size, name=name)

    # ------------------------------------------------------------------ properties
    @property
    def shape(self) -> tuple[int, int]:
        """Grid shape ``(ny, nx)``."""
        return (int(self.pressure.shape[0]), int(self.pressure.shape[1]))

    @property
    def n_active(self) -> int:
        """Number of cells with non-zero pressure."""
        return int(self.active.size)

    @property
    def half_extent(self) -> tuple[float, float]:
        """Half widths ``(X0, Y0) = (nx·h/2, ny·h/2)`` of the grid's bounding box [m]."""
        ny, nx = self.shape
        return (nx * self.cell_size / 2.0, ny * self.cell_size / 2.0)

    @property
    def total_normal_force(self) -> float:
        """``Σp·h²`` [N] -- the total normal force if the map was given as a pressure in Pa."""
        return self.scale * self.cell_size ** 2

    def cell_centres(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return ``(x, y)`` cell-centre coordinates [m], each of shape (ny, nx)."""
        ny, nx = self.shape
        h = self.cell_size
        xs = (np.arange(nx) + 0.5 - nx / 2.0) * h
        ys = -(np.arange(ny) + 0.5 - ny / 2.0) * h
        return np.broadcast_to(xs, (ny, nx)).copy(), np.broadcast_to(ys[:, None], (ny, nx)).copy()

    def normal_forces(self, f_n: float) -> NDArray[np.float64]:
        """Per-cell normal forces ``f_n·p̂`` [N], shape (ny, nx)."""
        return f_n * self.pressure

    def scaled(self, k: float) -> ContactSurface:
        """The same pressure shape with the cell size multiplied by ``k`` (spec §6.5)."""
        return ContactSurface(pressure=self.pressure, cell_size=self.cell_size * k,
                              name=self.name, scale=self.scale)

    def shape_key(self) -> str:
        """SHA-256 hex digest of the normalised map (shape, values); independent of ``h``.

        Values are quantised to 12 decimals of ``p̂/max p̂`` so that maps differing only in
        scale (and therefore in the last bits after normalisation) share a key.
        """
        digest = hashlib.sha256()
        digest.update(np.asarray(self.pressure.shape, dtype=np.int64).tobytes())
        quantised = np.round(self.pressure / self.pressure.max(), 12) + 0.0   # −0 → +0
        digest.update(np.ascontiguousarray(quantised, dtype='<f8').tobytes())
        return digest.hexdigest()

    def same_shape_as(self, other: ContactSurface) -> bool:
        """True when both normalised maps agree to round-off (only the cell size may differ)."""
        return (self.pressure.shape == other.pressure.shape
                and bool(np.allclose(self.pressure, other.pressure, rtol=1e-12, atol=0.0)))


# ---------------------------------------------------------------------- canonical shapes
def _grid(n: int) -> NDArray[np.float64]:
    if n < 1:
        raise ValueError(f'grid size n must be >= 1, got {n}')
    return np.zeros((n, n), dtype=np.float64)


def _middle(n: int) -> list[tuple[int, float]]:
    """Index/weight pairs of the middle column (or the two middle ones at ½ for even n)."""
    if n % 2:
        return [(n // 2, 1.0)]
    return [(n // 2 - 1, 0.5), (n // 2, 0.5)]


def square(n: int = 21, size: float = 0.02) -> ContactSurface:
    """Uniform square patch of side ``size`` [m] on an ``n × n`` grid (spec §3 "Square")."""
    p = _grid(n)
    p[:] = 1.0
    return ContactSurface(p, size / n, name='square')


def circle(n: int = 21, size: float = 0.02) -> ContactSurface:
    """Uniform jagged disc: cells with ``(i − c)² + (j − c)² ≤ c²``, ``c = (n − 1)/2``.

    For odd n this is the reference's ``c = n//2`` rule (317 cells at n = 21, equal-area
    radius ≈ 0.957 R); for even n the disc stays centred on the grid.
    """
    c = (n - 1) / 2.0
    idx = np.arange(n) - c
    mask = idx[None, :] ** 2 + idx[:, None] ** 2 <= c * c
    return ContactSurface(mask.astype(np.float64), size / n, name='circle')


def line(n: int = 21, size: float = 0.02) -> ContactSurface:
    """Uniform line along y on the middle column (x = 0) (spec §3 "Line")."""
    p = _grid(n)
    for i, w in _middle(n):
        p[:, i] = w
    return ContactSurface(p, size / n, name='line')


def line_grad(n: int = 21, size: float = 0.02) -> ContactSurface:
    """Middle column with ``p ∝ (n − j)``: largest at the +y edge; CoP (0, +3.175 mm) at n=21."""
    p = _grid(n)
    ramp = (n - np.arange(n)).astype(np.float64)
    for i, w in _middle(n):
        p[:, i] = w * ramp
    return ContactSurface(p, size / n, name='line_grad')


def line_grad_x(n: int = 21, size: float = 0.02) -> ContactSurface:
    """Middle row with ``p ∝ (n − i)``: largest at −x; CoP (−3.175 mm, 0) at n = 21."""
    p = _grid(n)
    ramp = (n - np.arange(n)).astype(np.float64)
    for j, w in _middle(n):
        p[j, :] = w * ramp
    return ContactSurface(p, size / n, name='line_grad_x')


def non_convex_1(n: int = 21, size: float = 0.02) -> ContactSurface:
    """Two uniform ``n_b × n_b`` blobs (``n_b = ⌊0.15 n⌋``) on the middle rows at both edges."""
    nb = max(1, math.floor(0.15 * n))
    r0 = (n - nb) // 2
    p = _grid(n)
    p[r0:r0 + nb, :nb] = 1.0
    p[r0:r0 + nb, n - nb:] = 1.0
    return ContactSurface(p, size / n, name='non_convex_1')


def non_convex_2(n: int = 21, size: float = 0.02) -> ContactSurface:
    """Non-convex L-like pair of bars (spec §3 "NonConvex2"); CoP ≈ (2.6, −0.2) mm at n = 21.

    A horizontal bar of 3 rows × ⌊0.7 n⌋ columns from the left edge plus a vertical bar of
    ⌊0.7 n⌋ rows × 3 columns at the right edge, both centred vertically with round-half-even
    as the reference does.
    """
    if n < 4:
        raise ValueError('non_convex_2 needs n >= 4')
    m = math.floor(0.7 * n)
    p = _grid(n)
    r_bar = round(n / 2.0 - 1.5)       # Python's round() is round-half-even
    r_col = round(n / 2.0 - m / 2.0)
    p[r_bar:r_bar + 3, :m] = 1.0
    p[r_col:r_col + m, n - 3:] = 1.0
    return ContactSurface(p, size / n, name='non_convex_2')


def soft_finger(f_n: float, n: int = 21, size: float = 0.02,
                k: float | None = 2.0) -> ContactSurface:
    """Load-dependent soft-finger map (spec §3): ``p(r) ∝ (1 − (r/a)^k)^(1/k)`` for ``r ≤ a``.

    Args:
        f_n: Normal force [N]; the contact radius is ``a = 6·f_n^(1/3)`` cells, capped at n/2.
        n: Grid size.
        size: Patch side [m].
        k: Shape exponent; ``None`` selects the load-sharpened ``k = f_n/0.5``.

    Returns:
        The surface (pressure normalised; the constant ``c_k`` cancels).
    """
    if f_n <= 0.0:
        raise ValueError(f'soft_finger needs f_n > 0, got {f_n!r}')
    kk = f_n / 0.5 if k is None else float(k)
    a = min(6.0 * f_n ** (1.0 / 3.0), n / 2.0)
    c = (n - 1) / 2.0
    idx = np.arange(n) - c
    r = np.sqrt(idx[None, :] ** 2 + idx[:, None] ** 2)
    inside = r <= a
    p = np.zeros((n, n))
    p[inside] = (1.0 - (r[inside] / a) ** kk) ** (1.0 / kk)
    name = 'soft_finger_k2' if k is not None else 'soft_finger_kf'
    return ContactSurface(p, size / n, name=name)


_CONSTRUCTORS = {
    'square': square,
    'circle': circle,
    'line': line,
    'line_grad': line_grad,
    'line_grad_x': line_grad_x,
    'non_convex_1': non_convex_1,
    'non_convex_2': non_convex_2,
}


def _canonical_name(name: str) -> str:
    key = name.strip().lower().replace('-', '_')
    # Accept the C++ CamelCase names (LineGrad, LineGradX, NonConvex1, ...).
    compact = key.replace('_', '')
    for candidate in _CONSTRUCTORS:
        if candidate.replace('_', '') == compact:
            return candidate
    raise ValueError(f'unknown surface {name!r}; choose one of {", ".join(STANDARD_SURFACES)}')


def standard_surface(name: str, n: int = 21, size: float = 0.02) -> ContactSurface:
    """Build a canonical surface by name (spec §3).

    Args:
        name: One of :data:`STANDARD_SURFACES` (C++ names such as ``'LineGrad'`` accepted).
        n: Cells per side.
        size: Patch side [m] (default 20 mm, i.e. R = 10 mm).

    Returns:
        The surface.
    """
    return _CONSTRUCTORS[_canonical_name(name)](n, size)
