# SPDX-License-Identifier: Apache-2.0
"""Pre-computed, normalised Coulomb limit surface of a pressure map (spec §6.1, §6.4, §6.5).

Paper §5.4. The unit twist at the centre of pressure (CoP) c, ω ≥ 0 half, is parameterised by
the direction of its linear part and an elevation,

    θ = atan2(vy, vx) ∈ [0, 2π),     ψ = atan2(‖v_t‖, r_a·|ω|) ∈ [0, π/2],

with ψ = 0 a pure rotation about the CoP and ψ = π/2 a pure translation. With ``n = n_ls``
segments per quadrant the nodes are ``θ_r = r·π/(2n)`` (r = 0…4n) and ``ψ_i = i·π/(2n)``
(i = 0…n); node twist ``ω = cos ψ_i``, ``v_t = r_a sin ψ_i (cos θ_r, sin θ_r)``. Each node holds
the steady Coulomb wrench at the CoP of the distributed model in **bilinear** mode (μ = f_n = 1,
σ2 = 0), normalised by ``f_t,max`` (pure translation) and ``τ_max`` (pure rotation about the
CoP): ``N[r, i] = (Fx/f_t,max, Fy/f_t,max, τ/τ_max)``, pointing against the motion.

The characteristic radius (spec §6.1) is ``r_a = τ_max/(μ f_n)`` in the same bilinear mode.

Build (vectorised over all nodes): the twist of node (r, i < n) is a rotation about
``CoR = c + r_a tan ψ_i (−sin θ_r, cos θ_r)``. Bilinear CoR smoothing only ever evaluates
rotations about *cell corners*, so the Coulomb wrenches of rotations about all
``(nx+1)(ny+1)`` corners are computed once (one vectorised sweep) and every node whose CoR lies
inside the grid box is a bilinear blend of four of them; nodes with the CoR outside the box
(and the translation row i = n, in closed form) are evaluated directly. For a rotation about
``p`` with ω > 0 the Coulomb sums are, with ``d = ρ − p``,

    F = (Σ p̂ d_y/‖d‖, −Σ p̂ d_x/‖d‖),      τ_c = −Σ p̂ ((ρ − c)·d)/‖d‖.

Lookup (spec §6.4): odd symmetry for ω < 0, then bilinear interpolation in (θ, ψ) with ψ
computed from the *current* r_a (size scaling, spec §6.5).
"""
from __future__ import annotations

import hashlib
import math
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .surfaces import ContactSurface

__all__ = [
    'LimitSurface',
    'LimitSurfaceCache',
    'ProgressCallback',
    'cache_key',
    'characteristic_radius',
    'corner_wrenches',
    'lookup_arrays',
    'lookup_scalar',
]

#: ``progress(fraction_done, elapsed_s)``; called only when a build takes longer than its
#: ``report_after_s`` threshold (1 s by default).
ProgressCallback = Callable[[float, float], None]

_FORMAT_VERSION = 1
_CHUNK_ELEMENTS = 1 << 17


def _rotation_wrenches(surface: ContactSurface, px: NDArray[np.float64],
                       py: NDArray[np.float64],
                       on_chunk: Callable[[int], None] | None = None) -> NDArray[np.float64]:
    """Coulomb wrenches at the CoP (μ = f_n = 1) of pure rotations (ω > 0) about points p.

    Args:
        surface: Contact surface.
        px: x of the rotation centres [m], shape (K,).
        py: y of the rotation centres [m], shape (K,).
        on_chunk: Called with the number of centres done after each vectorised chunk.

    Returns:
        (K, 3) array ``(Fx, Fy, τ_cop)``. No point may coincide with a cell centre.
    """
    x, y, w = surface.x, surface.y, surface.weights
    cx, cy = surface.cop
    wxc = w * (x - cx)
    wyc = w * (y - cy)
    out = np.empty((px.size, 3))
    step = max(1, _CHUNK_ELEMENTS // max(1, x.size))
    for k0 in range(0, px.size, step):
        dx = x - px[k0:k0 + step, None]
        dy = y - py[k0:k0 + step, None]
        inv = dx * dx
        inv += dy * dy
        np.sqrt(inv, out=inv)
        np.divide(1.0, inv, out=inv)
        dx *= inv
        dy *= inv
        out[k0:k0 + step, 0] = dy @ w
        out[k0:k0 + step, 1] = -(dx @ w)
        out[k0:k0 + step, 2] = -(dx @ wxc + dy @ wyc)
        if on_chunk is not None:
            on_chunk(min(k0 + step, px.size))
    return out


def corner_wrenches(surface: ContactSurface,
                    on_chunk: Callable[[int], None] | None = None) -> NDArray[np.float64]:
    """Coulomb wrenches at the CoP of unit-ω rotations about every cell corner.

    Args:
        surface: Contact surface.
        on_chunk: Called with the number of corners done after each vectorised chunk.

    Returns:
        (ny+1, nx+1, 3) array ``(Fx, Fy, τ_cop)`` for μ = f_n = 1, ω > 0, corners in
        ``[j, i]`` image order (corner row 0 at y = +ny·h/2).
    """
    ny, nx = surface.shape
    h = surface.cell_size
    cxs = (np.arange(nx + 1) - nx / 2.0) * h
    cys = (ny / 2.0 - np.arange(ny + 1)) * h
    px = np.broadcast_to(cxs, (ny + 1, nx + 1)).ravel()
    py = np.broadcast_to(cys[:, None], (ny + 1, nx + 1)).ravel()
    return _rotation_wrenches(surface, px, py, on_chunk).reshape(ny + 1, nx + 1, 3)


def _blend_corners(surface: ContactSurface, corners: NDArray[np.float64],
                   px: NDArray[np.float64], py: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bilinear blend of corner wrenches for rotation centres inside the grid box."""
    ny, nx = surface.shape
    h = surface.cell_size
    fi = px / h + nx / 2.0
    fj = ny / 2.0 - py / h
    i0 = np.clip(np.floor(fi), 0, nx - 1).astype(np.intp)
    j0 = np.clip(np.floor(fj), 0, ny - 1).astype(np.intp)
    di = (fi - i0)[:, None]
    dj = (fj - j0)[:, None]
    return ((1 - di) * (1 - dj) * corners[j0, i0] + di * (1 - dj) * corners[j0, i0 + 1]
            + (1 - di) * dj * corners[j0 + 1, i0] + di * dj * corners[j0 + 1, i0 + 1])


def characteristic_radius(surface: ContactSurface, bilinear: bool = True) -> float:
    """Characteristic radius ``r_a = |τ_rot|/(μ f_n)`` [m] of a surface (spec §6.1).

    Args:
        surface: Contact surface.
        bilinear: The reference method (Coulomb torque of a rotation about the CoP with
            bilinear CoR smoothing: a blend of rotations about the four surrounding cell
            corners); ``False`` gives the one-point value ``Σ p̂‖ρ − c‖``.

    Returns:
        r_a [m].
    """
    if not bilinear:
        return surface.r_a_cells
    ny, nx = surface.shape
    h = surface.cell_size
    cx, cy = surface.cop
    fi = cx / h + nx / 2.0
    fj = ny / 2.0 - cy / h
    i0 = min(max(math.floor(fi), 0), nx - 1)
    j0 = min(max(math.floor(fj), 0), ny - 1)
    di, dj = fi - i0, fj - j0
    px = (np.array([i0, i0 + 1, i0, i0 + 1]) - nx / 2.0) * h
    py = (ny / 2.0 - np.array([j0, j0, j0 + 1, j0 + 1])) * h
    weights = np.array([(1 - di) * (1 - dj), di * (1 - dj), (1 - di) * dj, di * dj])
    return abs(float(weights @ _rotation_wrenches(surface, px, py)[:, 2]))


def cache_key(surface: ContactSurface, n_ls: int) -> str:
    """Cache key: SHA-256 of the normalised map, ``n_ls``, the cell size and the format."""
    digest = hashlib.sha256()
    digest.update(surface.shape_key().encode())
    digest.update(f'|n_ls={int(n_ls)}|h={surface.cell_size!r}|v={_FORMAT_VERSION}'.encode())
    return digest.hexdigest()


@dataclass(frozen=True, eq=False)
class LimitSurface:
    """Normalised limit-surface table of one pressure shape (spec §6.4).

    Build with :meth:`build` (or through a :class:`LimitSurfaceCache`).

    Attributes:
        table: Node values, shape (4n+1, n+1, 3), read-only; ``[r, i]`` ↔ ``(θ_r, ψ_i)``.
        n_ls: Segments per quadrant ``n``.
        r_a: Bilinear characteristic radius at ``cell_size`` [m].
        cell_size: Cell side of the surface the table was built for [m].
        key: Cache key (:func:`cache_key`).
        source_shape: ``(ny, nx)`` of the source surface.
        shape_key: :meth:`ContactSurface.shape_key` of the source surface (size independent).
    """

    table: NDArray[np.float64]
    n_ls: int
    r_a: float
    cell_size: float
    key: str
    source_shape: tuple[int, int]
    shape_key: str
    flat: list[float] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        """Validate the table shape and cache a flat list for the scalar lookup path."""
        n = int(self.n_ls)
        if self.table.shape != (4 * n + 1, n + 1, 3):
            raise ValueError(f'table shape {self.table.shape} does not match n_ls = {n}')
        table = np.array(self.table, dtype=np.float64)
        table.setflags(write=False)
        object.__setattr__(self, 'table', table)
        object.__setattr__(self, 'n_ls', n)
        object.__setattr__(self, 'flat', table.ravel().tolist())

    # ------------------------------------------------------------------ build
    @classmethod
    def build(cls, surface: ContactSurface, n_ls: int = 20,
              progress: ProgressCallback | None = None,
              report_after_s: float = 1.0) -> LimitSurface:
        """Pre-compute the table for ``surface`` (vectorised over all nodes).

        Args:
            surface: Contact surface.
            n_ls: Segments per quadrant (default 20: 81 × 21 nodes).
            progress: Called as ``progress(fraction, elapsed_s)`` once the build has run
                longer than ``report_after_s`` (and at completion if it was called before).
            report_after_s: Reporting threshold [s].

        Returns:
            The table.
        """
        if n_ls < 1:
            raise ValueError(f'n_ls must be >= 1, got {n_ls}')
        t0 = time.perf_counter()   # progress reporting only; never affects results
        reported = False

        def report(fraction: float) -> None:
            nonlocal reported
            if progress is None:
                return
            elapsed = time.perf_counter() - t0
            if reported or elapsed > report_after_s:
                reported = True
                progress(fraction, elapsed)

        n = int(n_ls)
        ny, nx = surface.shape
        cx, cy = surface.cop
        theta = np.arange(4 * n + 1) * (math.pi / (2 * n))
        psi = np.arange(n + 1) * (math.pi / (2 * n))
        ct, st = np.cos(theta), np.sin(theta)
        # Rotation rows ψ < π/2: CoR = c + r_a tan ψ (−sin θ, cos θ). The four-corner r_a
        # places the nodes; the table is normalised with the same value from the corner sweep.
        r_nodes = characteristic_radius(surface)
        tan_psi = np.tan(psi[:n])
        px = (cx - r_nodes * tan_psi[None, :] * st[:, None]).ravel()
        py = (cy + r_nodes * tan_psi[None, :] * ct[:, None]).ravel()
        x0, y0 = surface.half_extent
        inside = (np.abs(px) <= x0) & (np.abs(py) <= y0)
        out_idx = np.flatnonzero(~inside)
        # Progress is proportional to rotation centres evaluated: corners, then outside nodes.
        n_corners = (ny + 1) * (nx + 1)
        total = n_corners + out_idx.size
        corners = corner_wrenches(surface, lambda done: report(done / total))
        r_a = _radius_from_corners(surface, corners)
        tau_max = r_a
        f_t_max = float(surface.weights.sum())
        values = np.empty((px.size, 3))
        values[inside] = _blend_corners(surface, corners, px[inside], py[inside])
        values[out_idx] = _rotation_wrenches(surface, px[out_idx], py[out_idx],
                                             lambda done: report((n_corners + done) / total))
        table = np.empty((4 * n + 1, n + 1, 3))
        table[:, :n, :] = values.reshape(4 * n + 1, n, 3)
        # Translation row ψ = π/2 (ω = 0): F = −v̂ Σp̂, τ_c = −(Σ p̂ (ρ − c)) × v̂.
        mx = float(surface.weights @ (surface.x - cx))
        my = float(surface.weights @ (surface.y - cy))
        table[:, n, 0] = -ct * f_t_max
        table[:, n, 1] = -st * f_t_max
        table[:, n, 2] = -(mx * st - my * ct)
        table[:, :, :2] /= f_t_max
        table[:, :, 2] /= tau_max
        if reported:
            report(1.0)
        return cls(table=table, n_ls=n, r_a=r_a, cell_size=surface.cell_size,
                   key=cache_key(surface, n), source_shape=surface.shape,
                   shape_key=surface.shape_key())

    # ------------------------------------------------------------------ lookup
    def lookup(self, vx: float, vy: float, omega: float,
               r_a: float | None = None) -> tuple[float, float, float]:
        """Normalised wrench ``h`` for one twist at the CoP (spec §6.4, scalar path).

        Args:
            vx: x velocity at the CoP [m/s].
            vy: y velocity at the CoP [m/s].
            omega: Angular velocity [rad/s].
            r_a: Current characteristic radius [m] (default: the table's).

        Returns:
            ``(h_x, h_y, h_τ)`` (force/f_t,max, force/f_t,max, torque/τ_max), against the
            motion; zeros for a zero twist.
        """
        ra = self.r_a if r_a is None else r_a
        return lookup_scalar(self.flat, self.n_ls, vx, vy, omega, ra)

    def lookup_batch(self, twists: ArrayLike, r_a: ArrayLike | None = None,
                     ) -> NDArray[np.float64]:
        """Vectorised :meth:`lookup` for (K, 3) twists at the CoP; returns (K, 3)."""
        tw = np.atleast_2d(np.asarray(twists, dtype=np.float64))
        ra = np.broadcast_to(np.asarray(self.r_a if r_a is None else r_a, dtype=np.float64),
                             tw.shape[:1])
        out = np.empty((3, tw.shape[0]))
        lookup_arrays(self.table.reshape(-1, 3), np.zeros(tw.shape[0], dtype=np.intp),
                      self.n_ls, tw[:, 0], tw[:, 1], tw[:, 2], ra, out)
        return out.T.copy()

    # ------------------------------------------------------------------ persistence
    def save(self, path: str | Path) -> Path:
        """Write the table to a ``.npz`` file; returns the path written."""
        p = Path(path)
        if p.suffix != '.npz':
            p = p.with_suffix('.npz')
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(p.name + '.tmp.npz')
        np.savez(tmp, table=self.table, n_ls=np.int64(self.n_ls), r_a=np.float64(self.r_a),
                 cell_size=np.float64(self.cell_size), key=np.str_(self.key),
                 source_shape=np.asarray(self.source_shape, dtype=np.int64),
                 shape_key=np.str_(self.shape_key), version=np.int64(_FORMAT_VERSION))
        tmp.replace(p)   # atomic: a concurrent reader never sees a partial file
        return p

    @classmethod
    def load(cls, path: str | Path, expected_key: str | None = None) -> LimitSurface:
        """Read a table written by :meth:`save`.

        Args:
            path: ``.npz`` file.
            expected_key: When given, the stored key must match (else ``ValueError``).

        Returns:
            The table.
        """
        with np.load(Path(path), allow_pickle=False) as data:
            version = int(data['version'])
            if version != _FORMAT_VERSION:
                raise ValueError(f'{path}: limit-surface format {version}, expected '
                                 f'{_FORMAT_VERSION}')
            key = str(data['key'])
            if expected_key is not None and key != expected_key:
                raise ValueError(f'{path}: stored key {key[:12]}… does not match '
                                 f'{expected_key[:12]}…')
            shape = tuple(int(v) for v in data['source_shape'])
            return cls(table=np.array(data['table']), n_ls=int(data['n_ls']),
                       r_a=float(data['r_a']), cell_size=float(data['cell_size']), key=key,
                       source_shape=(shape[0], shape[1]), shape_key=str(data['shape_key']))


def _radius_from_corners(surface: ContactSurface, corners: NDArray[np.float64]) -> float:
    """Bilinear r_a [m] from a precomputed :func:`corner_wrenches` table."""
    cx, cy = surface.cop
    return abs(float(_blend_corners(surface, corners, np.array([cx]), np.array([cy]))[0, 2]))


def lookup_scalar(flat: list[float], n: int, vx: float, vy: float, om: float,
                  r_a: float) -> tuple[float, float, float]:
    """Scalar bilinear table lookup with odd symmetry (spec §6.4 steps 1-4).

    Args:
        flat: The (4n+1, n+1, 3) table flattened in C order to a Python list (the scalar path
            avoids numpy's per-element overhead).
        n: Segments per quadrant.
        vx: x velocity at the CoP [m/s].
        vy: y velocity at the CoP [m/s].
        om: Angular velocity [rad/s].
        r_a: Current characteristic radius [m].

    Returns:
        ``(h_x, h_y, h_τ)``; zeros for a zero twist.
    """
    sign = 1.0
    if om < 0.0:
        vx, vy, om, sign = -vx, -vy, -om, -1.0
    vt = math.hypot(vx, vy)
    if vt == 0.0 and om == 0.0:
        return (0.0, 0.0, 0.0)
    theta = math.atan2(vy, vx)
    if theta < 0.0:
        theta += 2.0 * math.pi
    scale = 2.0 * n / math.pi
    a1 = theta * scale
    a2 = math.atan2(vt, r_a * om) * scale
    r = int(a1)
    if r > 4 * n - 1:
        r = 4 * n - 1
    i = int(a2)
    if i > n - 1:
        i = n - 1
    dr = a1 - r
    di = a2 - i
    row = 3 * (n + 1)
    b = r * row + 3 * i
    w00 = (1.0 - dr) * (1.0 - di)
    w10 = dr * (1.0 - di)
    w01 = (1.0 - dr) * di
    w11 = dr * di
    b10 = b + row
    b01 = b + 3
    b11 = b10 + 3
    t = flat
    return (sign * (w00 * t[b] + w10 * t[b10] + w01 * t[b01] + w11 * t[b11]),
            sign * (w00 * t[b + 1] + w10 * t[b10 + 1] + w01 * t[b01 + 1] + w11 * t[b11 + 1]),
            sign * (w00 * t[b + 2] + w10 * t[b10 + 2] + w01 * t[b01 + 2] + w11 * t[b11 + 2]))


def lookup_arrays(table_rows: NDArray[np.float64], base: NDArray[np.intp], n: int,
                  vx: NDArray[np.float64], vy: NDArray[np.float64],
                  om: NDArray[np.float64], r_a: NDArray[np.float64],
                  out: NDArray[np.float64]) -> NDArray[np.float64]:
    """Vectorised lookup over N twists at the CoP, possibly in different stacked tables.

    Args:
        table_rows: Stacked tables reshaped to (K·(4n+1)·(n+1), 3).
        base: Row offset of each twist's table, shape (N,).
        n: Segments per quadrant (shared by all tables).
        vx: (N,) x velocities at the CoPs [m/s].
        vy: (N,) y velocities [m/s].
        om: (N,) angular velocities [rad/s].
        r_a: (N,) current characteristic radii [m].
        out: (3, N) output buffer.

    Returns:
        ``out`` filled with ``(h_x, h_y, h_τ)``; zero columns for zero twists.
    """
    sign = np.where(om < 0.0, -1.0, 1.0)
    sx = vx * sign
    sy = vy * sign
    so = om * sign
    vt = np.hypot(sx, sy)
    scale = 2.0 * n / math.pi
    a1 = np.arctan2(sy, sx)
    a1 += (a1 < 0.0) * (2.0 * math.pi)
    a1 *= scale
    a2 = np.arctan2(vt, r_a * so)
    a2 *= scale
    r = np.minimum(a1.astype(np.intp), 4 * n - 1)
    i = np.minimum(a2.astype(np.intp), n - 1)
    dr = a1 - r
    di = a2 - i
    idx = base + r * (n + 1) + i
    w11 = dr * di
    w10 = dr - w11
    w01 = di - w11
    w00 = 1.0 - dr - w01
    res = (table_rows[idx].T * w00 + table_rows[idx + (n + 1)].T * w10
           + table_rows[idx + 1].T * w01 + table_rows[idx + (n + 2)].T * w11)
    res *= sign * ((vt > 0.0) | (so > 0.0))
    out[...] = res
    return out


class LimitSurfaceCache:
    """In-memory (LRU) and optional on-disk cache of limit-surface tables.

    Entries are keyed by :func:`cache_key` (normalised map, ``n_ls``, cell size). No module
    holds a global instance: create one and pass it to the models that should share tables.

    Args:
        directory: Folder for ``<key>.npz`` files (created on first save); ``None`` keeps the
            cache in memory only.
        max_entries: In-memory capacity (least recently used entries are dropped).
    """

    def __init__(self, directory: str | Path | None = None,
                 max_entries: int = 64) -> None:
        self._dir = None if directory is None else Path(directory)
        self._max = max(1, int(max_entries))
        self._mem: OrderedDict[str, LimitSurface] = OrderedDict()
        self.hits = 0
        self.disk_hits = 0
        self.builds = 0

    @property
    def directory(self) -> Path | None:
        """On-disk folder, or ``None``."""
        return self._dir

    def path_for(self, key: str) -> Path | None:
        """File that holds ``key`` (``None`` without a directory)."""
        return None if self._dir is None else self._dir / f'{key}.npz'

    def get(self, surface: ContactSurface, n_ls: int = 20,
            progress: ProgressCallback | None = None) -> LimitSurface:
        """Return the table for ``surface``, from memory, disk, or a fresh build (then saved).

        Args:
            surface: Contact surface.
            n_ls: Segments per quadrant.
            progress: Passed to :meth:`LimitSurface.build` on a miss.

        Returns:
            The table.
        """
        key = cache_key(surface, n_ls)
        ls = self._mem.get(key)
        if ls is not None:
            self._mem.move_to_end(key)
            self.hits += 1
            return ls
        path = self.path_for(key)
        if path is not None and path.is_file():
            try:
                ls = LimitSurface.load(path, expected_key=key)
                self.disk_hits += 1
            except (OSError, ValueError, KeyError):
                ls = None   # unreadable or stale file: rebuild and overwrite it
        if ls is None:
            ls = LimitSurface.build(surface, n_ls, progress=progress)
            self.builds += 1
            if path is not None:
                ls.save(path)
        self._mem[key] = ls
        while len(self._mem) > self._max:
            self._mem.popitem(last=False)
        return ls

    def clear(self) -> None:
        """Drop the in-memory entries (files stay)."""
        self._mem.clear()
