"""ament_python package friction_models.

The simulation's hot modules (``friction_models.core.native.COMPILED_MODULES``) are compiled
with mypyc when mypy is installed (it is in requirements.txt); without it, or with
``FRICTION_MODELS_COMPILE=0``, the package is pure Python. ``friction_models.core.native``
decides at import time which one runs and warns when the extensions are out of date.
"""
import importlib.util
import os
import sys
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = 'friction_models'
CORE = Path(PACKAGE) / 'core'


def _load_native():
    """friction_models.core.native, loaded by path (importing the package needs numpy)."""
    spec = importlib.util.spec_from_file_location('_fm_native', CORE / 'native.py')
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module   # dataclasses look their module up while decorating
    spec.loader.exec_module(module)
    return module


NATIVE = _load_native()


def compiled_core() -> list:
    """mypyc extensions of the hot simulation modules, or [] (pure Python)."""
    if not {'build_ext', 'develop', 'install', 'build', 'bdist_wheel'} & set(sys.argv):
        return []   # metadata queries (egg_info, --name, ...) leave any build untouched
    manifest = CORE / NATIVE.MANIFEST_NAME
    if manifest.exists():
        manifest.unlink()   # no manifest = no compiled core claimed until the build succeeds
    if os.environ.get('FRICTION_MODELS_COMPILE', '1') == '0':
        return []
    try:
        import mypy.version
        from mypyc.build import mypycify
    except ImportError:
        print('friction_models: mypy is not installed; the simulation core stays pure Python '
              '(about 2.5x slower)', file=sys.stderr)
        return []
    paths = [str(CORE / f'{m}.py') for m in NATIVE.COMPILED_MODULES]
    try:
        # '--config-file=': the workspace's mypy.ini (lint settings) must not change the build.
        extensions = mypycify(['--config-file=', '--ignore-missing-imports', *paths],
                              opt_level='3', group_name=f'{PACKAGE}.core._native')
    except (Exception, SystemExit) as exc:   # mypyc reports type errors by exiting
        print(f'friction_models: mypyc could not compile the simulation core ({exc!r}); it '
              'stays pure Python', file=sys.stderr)
        return []
    manifest.write_text(NATIVE.manifest_text(CORE, f'mypyc {mypy.version.__version__}'))
    return extensions

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    ext_modules=compiled_core(),
    package_data={PACKAGE + '.core': [NATIVE.MANIFEST_NAME, 'reference_objects.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='Slip cell maintainers',
    maintainer_email='maintainers@slip-cell.invalid',
    description=open('package.xml').read().split('<description>')[1].split('</description>')[0],
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'sim_gripper = friction_models.sim_gripper_node:main',
            'friction_models_cli = friction_models.cli:main',
        ],
    },
)
