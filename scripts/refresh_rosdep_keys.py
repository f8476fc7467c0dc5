"""
Rewrite tests/packaging/rosdep_keys.yaml from a full copy of rosdistro's rosdep folder.

Usage: python scripts/refresh_rosdep_keys.py ROSDEP_DIR [--revision COMMIT] [--output FILE]

ROSDEP_DIR holds ros/rosdistro's rosdep/base.yaml and rosdep/python.yaml (the rosdep folder
of a rosdistro checkout, or unmodified copies of the two files). The snapshot keeps the
entries of the keys package.xml declares, unchanged, and names the rosdistro commit they
come from: ``--revision``, else the commit a README.md in ROSDEP_DIR names, else the
folder's git HEAD. tests/packaging/test_package_xml.py checks package.xml against it.
"""

import argparse
from pathlib import Path
import re
import subprocess
import sys
from typing import Dict, Optional, Set
import xml.etree.ElementTree as ElementTree

import yaml

ROOT = Path(__file__).resolve().parents[1]
SNAPSHOT = ROOT / 'tests' / 'packaging' / 'rosdep_keys.yaml'

#: rosdistro's key files, in the order rosdep_keys() of the test merges them.
FILES = ('python.yaml', 'base.yaml')

#: package.xml's dependency tags.
TAGS = ('depend', 'build_depend', 'buildtool_depend', 'exec_depend', 'test_depend')

HEADER = """\
# The entries of ros/rosdistro's rosdep/python.yaml and rosdep/base.yaml for the keys that
# package.xml declares, unchanged, at the rosdistro commit below (ROS packages such as rclpy
# are keys by their own names and are in neither file). tests/packaging/test_package_xml.py
# checks package.xml against them; scripts/refresh_rosdep_keys.py writes this file.
"""


def declared_keys(package_xml: Path = ROOT / 'package.xml') -> Set[str]:
    """Return every dependency key package.xml declares."""
    root = ElementTree.parse(package_xml).getroot()
    return {element.text.strip() for tag in TAGS for element in root.iter(tag)
            if element.text}


def revision_of(folder: Path) -> Optional[str]:
    """Return the rosdistro commit of ``folder``: named in its README.md, or its git HEAD."""
    readme = folder / 'README.md'
    if readme.is_file():
        found = re.search(r'commit ([0-9a-f]{40})', readme.read_text())
        if found:
            return found.group(1)
    process = subprocess.run(['git', '-C', str(folder), 'rev-parse', 'HEAD'],
                             capture_output=True, text=True, timeout=30)
    return process.stdout.strip() if process.returncode == 0 else None


def snapshot(folder: Path, keys: Set[str]) -> Dict[str, Dict[str, dict]]:
    """Return file name -> the entries of ``keys`` in that rosdistro file."""
    entries: Dict[str, Dict[str, dict]] = {}
    for name in FILES:
        with open(folder / name) as stream:
            rules = yaml.load(stream, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader))
        entries[name] = {key: rules[key] for key in sorted(keys & set(rules))}
    return entries


def main() -> int:
    """Write the snapshot; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('rosdep_dir', type=Path,
                        help="folder with rosdistro's base.yaml and python.yaml")
    parser.add_argument('--revision', default=None,
                        help='rosdistro commit of the copy (default: from README.md or git)')
    parser.add_argument('--output', type=Path, default=SNAPSHOT, help='file to write')
    args = parser.parse_args()
    revision = args.revision or revision_of(args.rosdep_dir)
    if not revision:
        print(f'error: no rosdistro commit found for {args.rosdep_dir}: give --revision',
              file=sys.stderr)
        return 2
    document = {'rosdistro_commit': revision,
                'files': snapshot(args.rosdep_dir, declared_keys())}
    args.output.write_text(HEADER + yaml.safe_dump(document, default_flow_style=None,
                                                   sort_keys=False, width=99))
    return 0


if __name__ == '__main__':
    sys.exit(main())
