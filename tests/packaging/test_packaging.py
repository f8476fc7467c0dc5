"""`colcon build` of the package, as on a ROS workstation, from the tracked files only."""

from pathlib import Path
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[2]
COLCON = Path(sys.executable).parent / 'colcon'


def test_colcon_build_installs_package_and_params(tmp_path):
    """The ament_python build installs the code, package.xml, index marker and the YAML."""
    source = tmp_path / 'src' / 'cdr_translator'
    tracked = subprocess.run(['git', 'ls-files'], cwd=ROOT, capture_output=True, text=True,
                             check=True, timeout=30).stdout.split()
    for name in tracked:
        target = source / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, target)
    process = subprocess.run([str(COLCON), 'build', '--packages-select', 'cdr_translator'],
                             cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert process.returncode == 0, process.stdout + process.stderr
    share = tmp_path / 'install' / 'cdr_translator' / 'share'
    assert (share / 'cdr_translator' / 'config' / 'translator.yaml').is_file()
    assert (share / 'cdr_translator' / 'package.xml').is_file()
    for name in ('translator.launch.py', 'cdr.launch.py', 'launch_common.py'):
        assert (share / 'cdr_translator' / 'launch' / name).is_file(), name
    assert (share / 'ament_index' / 'resource_index' / 'packages' / 'cdr_translator').is_file()
    installed = list((tmp_path / 'install').glob('**/site-packages/cdr_translator/__init__.py'))
    assert installed, 'the library was not installed'
    # only the three libraries (and their metadata) go to site-packages: no bench, tests, scripts
    site = installed[0].parents[1]
    packages = {path.name for path in site.iterdir()
                if path.is_dir() and not path.name.endswith(('.egg-info', '.dist-info'))
                and path.name != '__pycache__'}
    assert packages == {'cdr_translator', 'cdr_wire', 'msg_tools'}, packages
    for subpackage in ('fidelity', 'robot', 'studies', 'interface', 'ros'):
        assert (site / 'cdr_translator' / subpackage / '__init__.py').is_file(), subpackage
    assert (site / 'cdr_translator' / 'py.typed').is_file()
    assert (site / 'msg_tools' / 'py.typed').is_file()
    assert (site / 'cdr_wire' / 'py.typed').is_file()
    assert (site / 'cdr_wire' / 'msg' / 'geometry_msgs' / 'WrenchStamped.msg').is_file()
    # the installed library finds the installed parameter file without the ament index
    check = subprocess.run(
        [sys.executable, '-c', 'from cdr_translator.params import DEFAULT_PARAMS_PATH as p; '
         'print(p)'], capture_output=True, text=True, timeout=60, cwd=tmp_path,
        env={'PYTHONPATH': str(installed[0].parents[1]), 'PATH': '/usr/bin:/bin'})
    assert check.returncode == 0, check.stderr
    assert Path(check.stdout.strip()) == share / 'cdr_translator' / 'config' / 'translator.yaml'
