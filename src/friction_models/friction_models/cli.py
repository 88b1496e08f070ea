# SPDX-License-Identifier: Apache-2.0
"""``friction_models_cli``: look at the friction models instead of reading about them.

Subcommands (``friction_models_cli <command> --help`` for the options):

* ``surfaces``       -- table of the canonical contact surfaces (cells, CoP, r_a, s_v).
* ``limit-surface``  -- the pre-computed limit surface of a surface: sections as a table,
  optionally a PNG (pressure map + sections, with the ellipsoid for comparison).
* ``stick-slip``     -- a mass pulled through a spring over an amended LuGre contact: time
  series as a table, optionally a PNG.
* ``compare``        -- reduced (limit surface and ellipsoid) vs distributed model on the 5 s
  twist profile of the paper: normalised RMSE table, optionally a PNG.

PNG output uses matplotlib with the non-interactive Agg backend.
"""
from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from slip_cell_common.core.cli_args import (
    Parser,
    finite_float,
    float_range,
    int_range,
    non_negative_float,
    positive_float,
    positive_int,
)

from .core.distributed import DistributedPlanarLuGre
from .core.limit_surface import LimitSurface, LimitSurfaceCache, characteristic_radius
from .core.params import PARAMETER_SETS, LuGreParams
from .core.reduced import ReducedPlanarLuGre
from .core.scenarios import simulate_stick_slip, twist_profile
from .core.surfaces import STANDARD_SURFACES, ContactSurface, standard_surface

__all__ = ['main']


def _pyplot() -> Any:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def _surface(args: argparse.Namespace) -> ContactSurface:
    return standard_surface(args.surface, n=args.n, size=args.size)


def _progress(stream: TextIO) -> Any:
    def report(fraction: float, elapsed_s: float) -> None:
        stream.write(f'\rlimit surface: {100 * fraction:5.1f} % ({elapsed_s:.1f} s)')
        if fraction >= 1.0:
            stream.write('\n')
        stream.flush()
    return report


def _cmd_surfaces(args: argparse.Namespace) -> int:
    print(f'{"surface":<14}{"cells":>6}{"CoP x [mm]":>12}{"CoP y [mm]":>12}'
          f'{"r_a cell [mm]":>15}{"r_a bil [mm]":>14}{"s_v3":>8}')
    for name in STANDARD_SURFACES:
        s = standard_surface(name, n=args.n, size=args.size)
        r_b = characteristic_radius(s, bilinear=True)
        print(f'{name:<14}{s.n_active:>6}{s.cop[0] * 1e3:>12.3f}{s.cop[1] * 1e3:>12.3f}'
              f'{s.r_a_cells * 1e3:>15.3f}{r_b * 1e3:>14.3f}{s.second_moment / r_b ** 2:>8.3f}')
    return 0


def _cmd_limit_surface(args: argparse.Namespace) -> int:
    surface = _surface(args)
    progress = _progress(sys.stderr)
    if args.cache_dir:
        ls = LimitSurfaceCache(args.cache_dir).get(surface, args.n_ls, progress=progress)
    else:
        ls = LimitSurface.build(surface, args.n_ls, progress=progress)
    n = ls.n_ls
    print(f'# {surface.name}: {surface.shape[1]}x{surface.shape[0]} cells of '
          f'{surface.cell_size * 1e3:.4g} mm, n_ls = {n}, r_a = {ls.r_a * 1e3:.4f} mm, '
          f'CoP = ({surface.cop[0] * 1e3:.3f}, {surface.cop[1] * 1e3:.3f}) mm')
    print('# h = (F_x/f_max, F_y/f_max, tau/tau_max) at the CoP, against the motion; '
          '|h| = 1 on the ellipsoid')
    print(f'{"theta [deg]":>11}{"psi [deg]":>10}{"h_x":>10}{"h_y":>10}{"h_tau":>10}{"|h|":>8}')
    step = max(1, n // args.rows)
    for r in range(0, 4 * n, n):
        for i in list(range(0, n + 1, step)) + ([n] if n % step else []):
            h = ls.table[r, i]
            print(f'{math.degrees(r * math.pi / (2 * n)):>11.1f}'
                  f'{math.degrees(i * math.pi / (2 * n)):>10.1f}'
                  f'{h[0]:>10.4f}{h[1]:>10.4f}{h[2]:>10.4f}{np.linalg.norm(h):>8.4f}')
    if args.png:
        _plot_limit_surface(surface, ls, Path(args.png))
        print(f'# wrote {args.png}')
    return 0


def _plot_limit_surface(surface: ContactSurface, ls: LimitSurface, path: Path) -> None:
    plt = _pyplot()
    n = ls.n_ls
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    x0, y0 = surface.half_extent
    ax = axes[0]
    ax.imshow(surface.pressure, extent=(-x0 * 1e3, x0 * 1e3, -y0 * 1e3, y0 * 1e3),
              cmap='viridis', origin='upper')
    ax.plot(surface.cop[0] * 1e3, surface.cop[1] * 1e3, 'r+', ms=12, label='CoP')
    ax.set(title=f'{surface.name}: normalised pressure', xlabel='x [mm]', ylabel='y [mm]')
    ax.legend(loc='upper right')
    circle = np.linspace(0.0, 2.0 * math.pi, 200)
    for ax, r, label in ((axes[1], 0, 'x'), (axes[2], n, 'y')):
        h = -ls.table[r, :, :]           # friction opposes the motion: plot −h (the LS)
        comp = 0 if label == 'x' else 1
        other = ls.table[(r + 2 * n) % (4 * n), :, :]
        ax.plot(h[:, comp], h[:, 2], 'b.-', label=f'v along +{label}')
        ax.plot(other[:, comp], other[:, 2], 'b.-')
        ax.plot(-h[:, comp], -h[:, 2], 'b.-')
        ax.plot(-other[:, comp], -other[:, 2], 'b.-')
        ax.plot(np.cos(circle), np.sin(circle), 'k--', lw=0.8, label='ellipsoid')
        ax.set(title=f'section in the {label}-τ plane', xlabel=f'F_{label}/f_t,max',
               ylabel='τ/τ_max', aspect='equal')
        ax.legend(loc='lower left', fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _cmd_stick_slip(args: argparse.Namespace) -> int:
    params = LuGreParams(mu_c=args.mu_c, mu_s=args.mu_s, v_s=args.v_s, sigma0=args.sigma0,
                         sigma1=args.sigma1, sigma2=args.sigma2)
    res = simulate_stick_slip(params, f_n=args.f_n, mass=args.mass, stiffness=args.stiffness,
                              drive_speed=args.drive_speed, duration=args.duration, dt=args.dt,
                              elasto_plastic=args.elasto_plastic)
    every = max(1, round(args.print_every / args.dt))
    print(f'# mu_c = {args.mu_c}, mu_s = {args.mu_s}, f_n = {args.f_n} N, '
          f'k = {args.stiffness} N/m, v_d = {args.drive_speed} m/s, dt = {args.dt} s')
    print(f'{"t [s]":>8}{"x [mm]":>11}{"v [mm/s]":>11}{"spring [N]":>12}{"friction [N]":>14}')
    for k in range(0, res.t.size, every):
        print(f'{res.t[k]:>8.3f}{res.x[k] * 1e3:>11.4f}{res.v[k] * 1e3:>11.4f}'
              f'{res.spring_force[k]:>12.4f}{res.friction[k]:>14.4f}')
    cycles = res.stick_phases(after=0.25 * args.duration)
    print(f'# stick-slip cycles after t = {0.25 * args.duration:g} s: {cycles}')
    if args.png:
        plt = _pyplot()
        fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
        axes[0].plot(res.t, res.x * 1e3, label='mass')
        axes[0].plot(res.t, res.t * res.drive_speed * 1e3, 'k--', lw=0.8, label='drive')
        axes[0].set(ylabel='position [mm]')
        axes[0].legend()
        axes[1].plot(res.t, res.v * 1e3)
        axes[1].set(ylabel='velocity [mm/s]')
        axes[2].plot(res.t, res.spring_force, label='spring')
        axes[2].plot(res.t, -res.friction, label='−friction')
        axes[2].set(ylabel='force [N]', xlabel='t [s]')
        axes[2].legend()
        fig.suptitle(f'stick-slip: μ_s = {args.mu_s}, μ_c = {args.mu_c} ({cycles} cycles)')
        fig.tight_layout()
        Path(args.png).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.png, dpi=110)
        plt.close(fig)
        print(f'# wrote {args.png}')
    return 0


def normalised_rmse(test: NDArray[np.float64], base: NDArray[np.float64],
                    ) -> tuple[float, float]:
    """Paper §6.4 error metrics for (K, 3) wrench series ``(fx, fy, τ)``.

    Returns:
        ``(RMSE(‖F_t − F_t,base‖)/max‖F_t,base‖, RMSE(τ − τ_base)/max|τ_base|)``.
    """
    df = np.hypot(test[:, 0] - base[:, 0], test[:, 1] - base[:, 1])
    f_scale = float(np.max(np.hypot(base[:, 0], base[:, 1])))
    t_scale = float(np.max(np.abs(base[:, 2])))
    return (float(np.sqrt(np.mean(df ** 2))) / f_scale,
            float(np.sqrt(np.mean((test[:, 2] - base[:, 2]) ** 2))) / t_scale)


def run_profile(model: Any, dt: float, duration: float = 5.0) -> NDArray[np.float64]:
    """Drive a planar model with the §10.1 CoP twist profile; (K, 3) wrenches at the CoP."""
    steps = round(duration / dt)
    twists = twist_profile(np.arange(steps) * dt)
    out = np.empty((steps, 3))
    for k in range(steps):
        w = model.step(twists[k], dt, frame='cop')
        out[k] = (w.fx, w.fy, w.tau_cop)
    return out


def _cmd_compare(args: argparse.Namespace) -> int:
    params = PARAMETER_SETS['reduced_vs_distributed']
    names = STANDARD_SURFACES if args.surface == 'all' else (args.surface,)
    print(f'# 5 s twist profile (spec §10.1), dt = {args.dt} s, exponential integrator, EP on; '
          'NRMSE vs the distributed model')
    print(f'{"surface":<14}{"LS force":>10}{"LS torque":>11}{"ell force":>11}{"ell torque":>12}')
    series = {}
    for name in names:
        s = standard_surface(name, n=args.n, size=args.size)
        dist = run_profile(DistributedPlanarLuGre(s, params), args.dt)
        red = run_profile(ReducedPlanarLuGre(s, params), args.dt)
        ell = run_profile(ReducedPlanarLuGre(s, params, limit_surface=False), args.dt)
        e_ls = normalised_rmse(red, dist)
        e_el = normalised_rmse(ell, dist)
        series[name] = (dist, red, ell)
        print(f'{name:<14}{e_ls[0]:>10.4f}{e_ls[1]:>11.4f}{e_el[0]:>11.4f}{e_el[1]:>12.4f}')
    if args.png:
        plt = _pyplot()
        name = names[0]
        dist, red, ell = series[name]
        t = np.arange(dist.shape[0]) * args.dt
        fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
        for c, label in enumerate(('f_x [N]', 'f_y [N]', 'τ at CoP [N·m]')):
            axes[c].plot(t, dist[:, c], 'k', lw=1.5, label='distributed')
            axes[c].plot(t, red[:, c], 'b--', label='reduced (limit surface)')
            axes[c].plot(t, ell[:, c], 'r:', label='reduced (ellipsoid)')
            axes[c].set(ylabel=label)
        axes[0].legend(fontsize=8)
        axes[2].set(xlabel='t [s]')
        fig.suptitle(f'{name}: reduced vs distributed')
        fig.tight_layout()
        Path(args.png).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.png, dpi=110)
        plt.close(fig)
        print(f'# wrote {args.png}')
    return 0


#: Most steps a stick-slip run may take (``duration / dt``): about a minute of computing.
MAX_STICK_SLIP_STEPS = 20_000_000


def _parser() -> Parser:
    parser = Parser(
        prog='friction_models_cli',
        description='Inspect the planar LuGre friction models: contact surfaces, pre-computed '
                    'limit surfaces, stick-slip, and reduced vs distributed accuracy. SI units '
                    'unless an option says otherwise.',
        epilog='Examples:\n'
               '  friction_models_cli surfaces\n'
               '  friction_models_cli limit-surface --surface line_grad --png ls.png\n'
               '  friction_models_cli stick-slip --mu-s 1.2 --png stick_slip.png\n'
               '  friction_models_cli compare --surface all --dt 5e-4')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', required=True,
                                help='what to show (COMMAND --help for its options)')
    cells = int_range(3, 201)

    def grid_args(p: argparse.ArgumentParser, with_all: bool = False) -> None:
        choices = STANDARD_SURFACES + (('all',) if with_all else ())
        p.add_argument('--surface', default='circle', choices=choices,
                       help='canonical contact surface' + (' (all: every one)' if with_all
                                                            else ''))
        p.add_argument('--n', type=cells, default=21,
                       help='pressure-grid cells per side, 3 to 201')
        p.add_argument('--size', type=positive_float, default=0.02,
                       help='patch side length [m]')

    p = sub.add_parser('surfaces', help='table of the canonical surfaces',
                       description='Cells, centre of pressure, characteristic radius r_a '
                                   '(one point per cell and bilinear) and viscous scale s_v3.')
    p.add_argument('--n', type=cells, default=21, help='pressure-grid cells per side, 3 to 201')
    p.add_argument('--size', type=positive_float, default=0.02, help='patch side length [m]')
    p.set_defaults(func=_cmd_surfaces)

    p = sub.add_parser('limit-surface', help='print or plot a pre-computed limit surface',
                       description='Build (or load from --cache-dir) the normalised limit '
                                   'surface and print its sections θ = 0, 90, 180, 270° over ψ '
                                   '(ψ = 0: rotation about the CoP, 90°: translation).')
    grid_args(p)
    p.add_argument('--n-ls', type=int_range(1, 200), default=20,
                   help='table segments per quadrant, 1 to 200 (more is finer and slower)')
    p.add_argument('--rows', type=positive_int, default=5,
                   help='ψ rows printed per section')
    p.add_argument('--cache-dir', default='',
                   help='folder for cached .npz tables (default: none, the table is built '
                        'every time)')
    p.add_argument('--png', default='', help='write a PNG figure to this path (default: none)')
    p.set_defaults(func=_cmd_limit_surface)

    p = sub.add_parser('stick-slip', help='print or plot a stick-slip time series',
                       description='Mass pulled through a spring over a 1-D amended LuGre '
                                   'contact. μ_s > μ_c gives stick-slip; μ_s = μ_c steady '
                                   'sliding.')
    p.add_argument('--mu-c', type=positive_float, default=1.0,
                   help='Coulomb (kinetic) friction coefficient [-]')
    p.add_argument('--mu-s', type=positive_float, default=1.2,
                   help='static friction coefficient [-], >= --mu-c')
    p.add_argument('--v-s', type=positive_float, default=1e-3,
                   help='Stribeck velocity [m/s]')
    p.add_argument('--sigma0', type=positive_float, default=1e5,
                   help='bristle stiffness [1/m]')
    p.add_argument('--sigma1', type=non_negative_float, default=20.0,
                   help='bristle damping [s/m]')
    p.add_argument('--sigma2', type=non_negative_float, default=1.0,
                   help='viscous coefficient [s/m]')
    p.add_argument('--f-n', type=positive_float, default=10.0, help='normal force [N]')
    p.add_argument('--mass', type=positive_float, default=1.0, help='pulled mass [kg]')
    p.add_argument('--stiffness', type=positive_float, default=1e4,
                   help='spring stiffness [N/m]')
    p.add_argument('--drive-speed', type=finite_float, default=1e-3,
                   help='speed of the spring\'s far end [m/s]')
    p.add_argument('--duration', type=positive_float, default=2.0,
                   help='simulated time [s]')
    p.add_argument('--dt', type=positive_float, default=1e-4,
                   help='integration step [s], at most --duration')
    p.add_argument('--elasto-plastic', action='store_true',
                   help='use the Elasto-Plastic law instead of plain LuGre')
    p.add_argument('--print-every', type=positive_float, default=0.05,
                   help='time between printed rows [s]')
    p.add_argument('--png', default='', help='write a PNG figure to this path (default: none)')
    p.set_defaults(func=_cmd_stick_slip)

    p = sub.add_parser('compare', help='reduced vs distributed accuracy (NRMSE)',
                       description='Run the 5 s twist profile of the paper through the '
                                   'distributed model and the reduced model with the limit '
                                   'surface and with the ellipsoid; print normalised RMSEs.')
    grid_args(p, with_all=True)
    p.add_argument('--dt', type=float_range(1e-6, 0.05), default=5e-4,
                   help='integration step [s], 1e-6 to 0.05')
    p.add_argument('--png', default='',
                   help='write a PNG of the first surface to this path (default: none)')
    p.set_defaults(func=_cmd_compare)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Console-script entry point; returns the process exit code (2: bad arguments, with
    one error line)."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command == 'stick-slip':
        if args.dt > args.duration:
            parser.error(f'stick-slip: --dt {args.dt:g} s is longer than --duration '
                         f'{args.duration:g} s')
        if args.duration / args.dt > MAX_STICK_SLIP_STEPS:
            parser.error(f'stick-slip: --duration / --dt = {args.duration / args.dt:.3g} steps; '
                         f'at most {MAX_STICK_SLIP_STEPS:.0e} (raise --dt or shorten --duration)')
    try:
        return int(args.func(args))
    except ValueError as exc:
        text = ' '.join(str(exc).split())
        print(f'friction_models_cli: error: {text}', file=sys.stderr, flush=True)
        return 2


if __name__ == '__main__':
    sys.exit(main())
