"""
The docs build with Sphinx as rosdoc2 builds them, and warnings are errors.

``python -m sphinx -W --keep-going`` reads docs/ (MyST Markdown, the API from the
docstrings by autodoc, the command lines' own ``--help``) into a temporary folder: a broken
link or cross-reference, a page outside every table of contents, a docstring autodoc cannot
read or a public name that no longer imports fails it.
"""

from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[2]
#: Seconds the whole build may take (autodoc imports the package; about 10-30 s).
BUILD_TIMEOUT_S = 600.0


def test_docs_build_without_warnings(tmp_path):
    """The HTML build succeeds with -W and documents the public API and the commands."""
    out = tmp_path / 'html'
    process = subprocess.run(
        [sys.executable, '-m', 'sphinx', '-W', '--keep-going', '-q', '-b', 'html',
         '-d', str(tmp_path / 'doctrees'), str(ROOT / 'docs'), str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
    assert process.returncode == 0, process.stdout + process.stderr
    api = (out / 'reference' / 'api.html').read_text(encoding='utf-8')
    for name in ('cdr_translator.TranslatorSolver.solve', 'cdr_translator.SolveResult',
                 'cdr_translator.fidelity.FidelitySolver', 'cdr_translator.robot.DeltaRobot'):
        assert f'id="{name}"' in api, f'{name} is not in the API reference'
    cli = (out / 'reference' / 'cli.html').read_text(encoding='utf-8')
    assert 'usage: python -m cdr_translator solve' in cli and '--force' in cli
    assert (out / 'tutorial' / 'getting_started.html').is_file()
    for page in out.rglob('*.html'):  # defaults as written, not this machine's paths
        assert str(ROOT) not in page.read_text(encoding='utf-8'), f'{page.name} shows {ROOT}'
