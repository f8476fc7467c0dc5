"""
The documentation as text: a short README, links that resolve, a Python example that runs.

The Sphinx build of docs/ (cross-references, tables of contents, the API from the
docstrings) is tests/packaging/test_docs_build.py; these checks read the Markdown as GitHub
shows it.
"""

import contextlib
import io
from pathlib import Path
import re

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / 'README.md'
#: Markdown pages outside docs/ that GitHub shows a reader (a folder's README).
FOLDER_READMES = [ROOT / 'bags' / 'README.md']
DOCS = sorted(path for path in (ROOT / 'docs').rglob('*.md') if '_build' not in path.parts)
#: The README stays a front page; everything else lives in docs/.
README_MAX_BYTES = 12 * 1024
#: The marker line right above the README's fenced Python block that this test runs.
SOLVE_MARKER = '<!-- docs-test: readme-solve -->'

FENCE = re.compile(r'^```.*?^```', re.MULTILINE | re.DOTALL)
LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)\)')
HEADING = re.compile(r'^#{1,6}\s+(.*?)\s*#*\s*$', re.MULTILINE)
#: A repository path named in the docs (`cdr_translator/ros/runtime.py`, `config/...yaml`).
CODE_PATH = re.compile(r'`((?:cdr_translator|cdr_wire|msg_tools|bench|scripts|config|launch|tests)'
                       r'/[\w/.-]*\w\.(?:py|yaml|md|mcap|png|json))`')
#: A dotted name in the package (`cdr_translator.studies.hard_cases.stability`).
DOTTED = re.compile(r'`((?:cdr_translator|cdr_wire|msg_tools)(?:\.\w+)+)`')
DEFINED = re.compile(r'^\s*(?:def|class)\s+(\w+)|^(\w+)\s*[:=]', re.MULTILINE)
#: A benchmark log or a to-do list in the docs: measured figures live in bench/results/, and
#: what would remove a limit belongs in the code's future (written so as not to match itself).
DIARY = re.compile(r'what would (?:remove|reach)[ ]', re.IGNORECASE)
#: Journal wording: history belongs in CHANGELOG.rst and git, not in docs, code or tests.
#: (Written with a character class so that this file does not match its own pattern.)
JOURNAL = re.compile(r'session [0-9]|\bissue[ -]?#?[0-9]|this[ ]branch|\*\*changed', re.IGNORECASE)
#: Where journal wording is looked for (CHANGELOG.rst is the one place for history).
JOURNAL_PLACES = ('docs', 'README.md', 'tests', 'cdr_translator', 'cdr_wire', 'msg_tools',
                  'bench', 'scripts', 'bags/README.md', 'config', 'launch', '.ci/run',
                  'Makefile', 'requirements.txt', 'setup.py', 'setup.cfg', 'package.xml',
                  'mypy.ini', 'pytest.ini')
JOURNAL_SUFFIXES = {'.md', '.py', '.rst', '.txt', '.yaml', '.cfg'}
#: A path outside the repository: the parent of the checkout, or an absolute path.
OUTSIDE_PATH = re.compile(r'\.\./shared|(?<![\w.~])/(?:home|tmp|work|root|mnt)/')


def _prose(text: str) -> str:
    """Return ``text`` without its fenced code blocks."""
    return FENCE.sub('', text)


def _anchors(path: Path) -> set:
    """Return GitHub's heading anchors of a Markdown file."""
    anchors = set()
    for heading in HEADING.findall(_prose(path.read_text(encoding='utf-8'))):
        plain = re.sub(r'[`*]|\[([^\]]*)\]\([^)]*\)', r'\1', heading)
        anchors.add(re.sub(r'[^\w\- ]', '', plain.strip().lower()).replace(' ', '-'))
    return anchors


def _relative_links(path: Path) -> list:
    """Return (target, fragment) of every relative link in ``path``'s prose."""
    links = []
    for target in LINK.findall(_prose(path.read_text(encoding='utf-8'))):
        if re.match(r'^[a-z][a-z0-9+.-]*:', target):
            continue  # http:, https:, mailto: ...
        file_part, _, fragment = target.partition('#')
        links.append((file_part, fragment))
    return links


def test_readme_is_short():
    """README.md is at most 12 KB, so that the node and the examples stay near the top."""
    size = len(README.read_bytes())
    assert size <= README_MAX_BYTES, f'README.md is {size} bytes: move text to docs/'


@pytest.mark.parametrize('path', [README, ROOT / 'docs' / 'tutorial' / 'getting_started.md'],
                         ids=lambda path: path.name)
def test_a_new_user_sets_the_ros_domain_and_discovery_range(path):
    """Where a new user starts the node, both variables are set, the domain within 1-101."""
    text = path.read_text(encoding='utf-8')
    domain = re.search(r'export .*ROS_DOMAIN_ID=(\d+)', text)
    assert domain and 1 <= int(domain.group(1)) <= 101, path
    assert re.search(r'export .*ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST', text), path
    assert text.index('ROS_DOMAIN_ID=') < text.index('.venv/bin/translator_node'), path


def test_docs_exist():
    """The pages the README and the tables of contents point to are there, one kind per folder."""
    names = {path.relative_to(ROOT / 'docs').as_posix() for path in DOCS}
    for name in ('index.md', 'tutorial/getting_started.md', 'howto/install.md',
                 'howto/run_nodes.md', 'howto/replay.md', 'howto/measurements.md',
                 'reference/api.md', 'reference/cli.md', 'reference/nodes.md',
                 'reference/parameters.md', 'reference/files.md', 'explanation/model.md',
                 'explanation/numerical_design.md'):
        assert name in names, name


@pytest.mark.parametrize('path', [README] + FOLDER_READMES + DOCS,
                         ids=lambda path: path.relative_to(ROOT).as_posix())
def test_relative_links_resolve(path):
    """Every relative link (and its #anchor, if a Markdown heading) points to something."""
    links = _relative_links(path)
    assert links or path not in [README] + FOLDER_READMES, f'{path.name} links to nothing'
    for file_part, fragment in links:
        target = (path.parent / file_part).resolve() if file_part else path
        assert target.exists(), f'{path.name}: broken link {file_part}'
        if fragment and target.suffix == '.md':
            assert fragment in _anchors(target), f'{path.name}: no #{fragment} in {target.name}'


def _names_defined(path: Path) -> set:
    """Return the names a module defines (def, class, or a top-level assignment)."""
    pairs = DEFINED.findall(path.read_text(encoding='utf-8'))
    return {name for pair in pairs for name in pair if name}


def _resolves(dotted: str) -> bool:
    """Tell whether a dotted name is a module, package or a name one of them defines."""
    parts = dotted.split('.')
    for cut in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:cut])
        module = base / '__init__.py' if base.is_dir() else base.with_suffix('.py')
        if module.is_file():
            rest = parts[cut:]
            return not rest or (len(rest) <= 2 and rest[0] in _names_defined(module))
    return False


@pytest.mark.parametrize('path', [README] + DOCS, ids=lambda path: path.name)
def test_code_paths_and_names_exist(path):
    """Files and dotted names the docs cite are in the repository (no stale module paths)."""
    text = path.read_text(encoding='utf-8')
    for cited in CODE_PATH.findall(text):
        assert (ROOT / cited).exists(), f'{path.name} cites {cited}, which does not exist'
    for cited in DOTTED.findall(text):
        assert _resolves(cited), f'{path.name} cites {cited}, which does not resolve'


def test_readme_solve_example_runs():
    """The README's Python solve example runs as printed and converges."""
    text = README.read_text(encoding='utf-8')
    assert SOLVE_MARKER in text
    block = re.search(r'```python\n(.*?)```', text[text.index(SOLVE_MARKER):], re.DOTALL)
    assert block is not None, f'no python block after {SOLVE_MARKER}'
    output = io.StringIO()
    with contextlib.redirect_stdout(output):
        exec(compile(block.group(1), 'README.md', 'exec'), {'__name__': 'readme_example'})
    first_line = output.getvalue().splitlines()[0]
    assert abs(float(first_line) - 22.28) < 0.01  # the PJ angle the comment states


@pytest.mark.parametrize('path', DOCS, ids=lambda path: path.name)
def test_docs_are_no_benchmark_log(path):
    """No page lists what would remove a limit: figures are in bench/results/, plans in code."""
    found = [line.strip() for line in path.read_text(encoding='utf-8').splitlines()
             if DIARY.search(line)]
    assert not found, f'{path.name}: ' + '; '.join(found)


def _journal_files() -> list:
    """Return the text files where journal wording is looked for."""
    files = []
    for place in JOURNAL_PLACES:
        base = ROOT / place
        if base.is_file():
            files.append(base)
            continue
        for path in sorted(base.rglob('*')):
            skipped = {'__pycache__', '.hypothesis'} & set(path.parts)
            if path.is_file() and path.suffix in JOURNAL_SUFFIXES and not skipped:
                files.append(path)
    return files


def test_no_journal_wording():
    """Docs, code and tests say what is, not which session or issue changed it."""
    found = []
    for path in _journal_files():
        for number, line in enumerate(path.read_text(encoding='utf-8').splitlines(), 1):
            if JOURNAL.search(line):
                found.append(f'{path.relative_to(ROOT)}:{number}: {line.strip()[:80]}')
    assert not found, 'history belongs in CHANGELOG.rst:\n' + '\n'.join(found)


@pytest.mark.parametrize('path', [README] + DOCS, ids=lambda path: path.name)
def test_no_paths_outside_the_repository(path):
    """The docs refer to nothing outside the repository (no ../shared, no absolute paths)."""
    text = path.read_text(encoding='utf-8')
    assert not OUTSIDE_PATH.search(text), f'{path.name}: {OUTSIDE_PATH.search(text).group()}'
    for file_part, _ in _relative_links(path):
        if file_part:
            target = (path.parent / file_part).resolve()
            assert ROOT in target.parents, f'{path.name} links outside the repository: {file_part}'


def test_params_file_states_the_refinement_limit_of_the_code():
    """config/translator.yaml's comment on the refinement gives the code's step limit."""
    text = (ROOT / 'config' / 'translator.yaml').read_text(encoding='utf-8')
    stated = re.findall(r'at most (\d+)\)', text)
    limit = re.search(r'^MAX_STEPS_PER_SEGMENT = (\d+)$', (
        ROOT / 'cdr_translator' / 'params' / 'translator_params.py').read_text(
            encoding='utf-8'), re.MULTILINE)
    assert limit is not None and stated == [limit.group(1)]


def test_the_two_atlas_rates_say_why_they_differ():
    """
    Two benchmark files rate the full-leg atlas: each says under what conditions.

    robot_levels.md times one chunk in one process, atlas_scale.md the `atlas` command's
    chunks on Dask workers with Zarr writes: each names the other, and the benchmarks page
    explains the difference, so that two different samples/s do not read as a contradiction.
    """
    results = ROOT / 'bench' / 'results'
    levels = (results / 'robot_levels.md').read_text(encoding='utf-8')
    scale = (results / 'atlas_scale.md').read_text(encoding='utf-8')
    assert 'one chunk' in levels and 'no Dask, no Zarr' in levels
    assert 'atlas_scale.md' in levels
    assert 'Each chunk starts cold' in scale and 'robot_levels.md' in scale
    page = (ROOT / 'docs' / 'howto' / 'benchmarks.md').read_text(encoding='utf-8')
    section = page.split('## Two atlas rates', 1)[1].split('\n## ', 1)[0]
    assert 'robot_levels.md' in section and 'atlas_scale.md' in section
    assert 'starts cold' in section and 'Dask' in section
