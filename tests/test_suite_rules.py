"""The suite's own rule (conftest.py at the repository root): under CECO_REQUIRE_EXTRAS=1, as .ci/run sets it,
a skipped test fails the session and is named with its reason; without it a skip stays a skip."""

import os
import pathlib
import shutil
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

SKIPPING = '''
import pytest
def test_runs():
    assert 1 + 1 == 2
def test_skips():
    pytest.skip("the reason it gives")
'''

MODULE_SKIP = '''
import pytest
pytest.importorskip("ceco_no_such_module_for_the_rule")
def test_never_collected():
    assert False
'''


def _pytest(tmp_path: pathlib.Path, body: str, require: bool) -> subprocess.CompletedProcess:
    shutil.copy(ROOT / 'conftest.py', tmp_path / 'conftest.py')
    (tmp_path / 'pytest.ini').write_text('[pytest]\n')
    (tmp_path / 'test_rule.py').write_text(body)
    (tmp_path / 'test_other.py').write_text('def test_other_runs():\n    assert 2 * 2 == 4\n')
    env = {k: v for k, v in os.environ.items() if k != 'CECO_REQUIRE_EXTRAS'}
    if require:
        env['CECO_REQUIRE_EXTRAS'] = '1'
    return subprocess.run(
        [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '--rootdir', str(tmp_path), str(tmp_path)],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=120,
        check=False,
    )


@pytest.mark.parametrize('body', [SKIPPING, MODULE_SKIP], ids=['test-skip', 'module-importorskip'])
def test_a_skip_fails_the_session_under_ci_and_says_which_and_why(tmp_path, body):
    out = _pytest(tmp_path, body, require=True)
    assert out.returncode == 1, out.stdout + out.stderr
    assert '1 skipped with CECO_REQUIRE_EXTRAS=1' in out.stdout
    if body is SKIPPING:
        assert 'test_rule.py::test_skips: Skipped: the reason it gives' in out.stdout
        assert '2 passed, 1 skipped' in out.stdout
    else:
        assert "test_rule.py: Skipped: could not import 'ceco_no_such_module_for_the_rule'" in out.stdout
        assert '1 passed, 1 skipped' in out.stdout


def test_without_the_ci_switch_a_skip_is_a_skip(tmp_path):
    out = _pytest(tmp_path, SKIPPING, require=False)
    assert out.returncode == 0, out.stdout + out.stderr
    assert '2 passed, 1 skipped' in out.stdout
    assert 'CECO_REQUIRE_EXTRAS=1' not in out.stdout


def test_a_failure_keeps_its_own_exit_status_under_ci(tmp_path):
    out = _pytest(tmp_path, SKIPPING + '\ndef test_fails():\n    assert 1 == 2\n', require=True)
    assert out.returncode == 1, out.stdout + out.stderr
    assert '1 failed, 2 passed, 1 skipped' in out.stdout
    assert '1 skipped with CECO_REQUIRE_EXTRAS=1' in out.stdout
