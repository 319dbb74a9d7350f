"""Pure parts of ceco_bringup.supervisor: which ROS_DOMAIN_ID a `ceco run`
uses, namespace names, and how children are started."""

from __future__ import annotations

import os

import pytest

from ceco_bringup import supervisor


def test_user_domain_id_is_used_for_every_run():
    # --domain-id first, then the user's ROS_DOMAIN_ID, the same for every strategy of --strategy all
    assert supervisor.resolve_domain_id(7, 0, {'ROS_DOMAIN_ID': '42'}) == (7, True)
    assert supervisor.resolve_domain_id(None, 0, {'ROS_DOMAIN_ID': '42'}) == (42, True)
    assert supervisor.resolve_domain_id(None, 3, {'ROS_DOMAIN_ID': ' 42 '}) == (42, True)
    assert supervisor.resolve_domain_id(None, 0, {'ROS_DOMAIN_ID': '0'}) == (0, True)
    assert supervisor.resolve_domain_id(232, 4, {}) == (232, True)


def test_private_domain_ids_differ_per_run_and_stay_in_range(monkeypatch):
    monkeypatch.setenv('CECO_DOMAIN_ID', '100')
    ids = [supervisor.resolve_domain_id(None, i, {'ROS_DOMAIN_ID': ''}) for i in range(5)]
    assert ids == [(100, False), (101, False), (1, False), (2, False), (3, False)]
    monkeypatch.delenv('CECO_DOMAIN_ID')
    ids = {supervisor.resolve_domain_id(None, i, {})[0] for i in range(5)}
    assert len(ids) == 5 and all(1 <= d <= 101 for d in ids)


@pytest.mark.parametrize(
    'environ, explicit, message',
    [
        ({'ROS_DOMAIN_ID': 'abc'}, None, "ROS_DOMAIN_ID='abc': must be an integer in 0..232"),
        ({'ROS_DOMAIN_ID': '-1'}, None, "ROS_DOMAIN_ID='-1': must be an integer in 0..232"),
        ({'ROS_DOMAIN_ID': '233'}, None, 'ROS_DOMAIN_ID=233: must be an integer in 0..232'),
        ({}, 500, '--domain-id=500: must be an integer in 0..232'),
    ],
)
def test_invalid_domain_id_is_refused(environ, explicit, message):
    with pytest.raises(ValueError) as err:
        supervisor.resolve_domain_id(explicit, 0, environ)
    assert str(err.value) == message


@pytest.mark.parametrize(
    'given, expected',
    [('', ''), (None, ''), ('/', ''), ('veh1', '/veh1'), ('/veh1/', '/veh1'), ('fleet/veh_2', '/fleet/veh_2')],
)
def test_namespace_normalized(given, expected):
    assert supervisor.normalize_namespace(given) == expected


@pytest.mark.parametrize('bad', ['1veh', 'veh-1', 'veh 1', 'a//b', 'veh__1'])
def test_invalid_namespace_refused(bad):
    with pytest.raises(ValueError, match='invalid namespace'):
        supervisor.normalize_namespace(bad)


def test_children_get_a_parent_death_signal_without_preexec_fn(tmp_path, monkeypatch):
    """The command line carries `setpriv --pdeathsig SIGINT --` where setpriv
    exists (Debian, Ubuntu), and the namespace remap; no preexec_fn."""
    import inspect

    assert 'preexec_fn' not in inspect.getsource(supervisor.NodeProcess.start)
    prefix = supervisor._die_with_parent_prefix()
    assert prefix[1:] == ['--pdeathsig', 'SIGINT', '--'] and prefix[0].endswith('setpriv')
    monkeypatch.setattr(supervisor, 'find_executable', lambda pkg, exe: f'/x/lib/{pkg}/{exe}')
    proc = supervisor.NodeProcess(
        'p', 'ceco_v2x_preview', 'preview_node', env={}, log_dir=tmp_path, namespace='veh1', params={'horizon_steps': 9}
    )
    assert proc.cmd == [
        '/x/lib/ceco_v2x_preview/preview_node',
        '--ros-args',
        '-r',
        '__ns:=/veh1',
        '-p',
        'horizon_steps:=9',
    ]
    # start() runs that prefix before the command line (a real process: `true` in place of the node)
    import shutil
    import subprocess

    monkeypatch.setattr(supervisor, 'find_executable', lambda pkg, exe: shutil.which('true'))
    started = []
    real_popen = subprocess.Popen

    def popen(argv, **kw):
        started.append(list(argv))
        return real_popen(argv, **kw)

    monkeypatch.setattr(supervisor.subprocess, 'Popen', popen)
    proc = supervisor.NodeProcess('p', 'ceco_v2x_preview', 'preview_node', env={}, log_dir=tmp_path)
    proc.start()
    assert started == [prefix + proc.cmd] and proc.proc.wait(timeout=30) == 0 and proc.starts == 1


def test_a_long_log_keeps_its_start_and_end_whole_lines_and_says_how_much_was_left_out(tmp_path, monkeypatch):
    log = tmp_path / 'c.log'
    lines = [f'line {i:05d} ' + 'x' * 40 + '\n' for i in range(1000)]  # 52 bytes each
    log.write_text(''.join(lines))
    size = log.stat().st_size
    assert supervisor.trim_log(log, keep_bytes=size) == 0 and log.stat().st_size == size  # not longer: untouched
    left_out = supervisor.trim_log(log, keep_bytes=1040)  # 520 bytes each side: 10 whole lines of 52
    out = log.read_text().splitlines(keepends=True)
    assert out[:10] == lines[:10] and out[-10:] == lines[-10:] and len(out) == 21
    assert left_out == size - 20 * 52 == 50960
    said = '[ceco: 50960 bytes of this log left out (longer than 1040 bytes); its start and its end are kept]\n'
    assert out[10] == said
    assert supervisor.trim_log(tmp_path / 'missing.log') == 0
    # a disk that is full when the trimmed copy is written: the log stays whole, no temporary file, no exception
    import errno
    import pathlib

    big = tmp_path / 'full' / 'c.log'
    big.parent.mkdir()
    big.write_text(''.join(lines))
    real_write = pathlib.Path.write_bytes

    def full_disk(self, data):
        real_write(self, data[: len(data) // 2])  # part of it written, then the disk is full
        raise OSError(errno.ENOSPC, 'No space left on device')

    monkeypatch.setattr(pathlib.Path, 'write_bytes', full_disk)
    assert supervisor.trim_log(big, keep_bytes=1040) == 0 and big.read_text() == ''.join(lines)
    assert sorted(p.name for p in big.parent.iterdir()) == ['c.log']


def test_a_stopped_child_that_wrote_more_than_the_cap_leaves_a_bounded_log(tmp_path):
    """A controller that prints 10 MB: its log after stop() is LOG_KEEP_BYTES plus one line, start and end kept."""
    import sys

    script = "import sys\nfor i in range(100000): sys.stdout.write(f'{i:07d} ' + 'y' * 92 + '\\n')\nprint('the end')\n"
    command = [sys.executable, '-c', script]
    proc = supervisor.NodeProcess('chatty', None, None, env={}, log_dir=tmp_path, command=command)
    proc.start()
    assert proc.proc.wait(timeout=60) == 0
    assert proc.log_path.stat().st_size > 10_000_000  # written whole while it runs
    assert proc.stop() == 0
    text = proc.log_text()
    assert supervisor.LOG_KEEP_BYTES - 200 <= len(text.encode()) <= supervisor.LOG_KEEP_BYTES + 200
    assert text.startswith('--- start 1: ') and '\n0000000 ' in text
    assert text.endswith('0099999 ' + 'y' * 92 + '\nthe end\n')
    assert text.count('bytes of this log left out') == 1


def test_what_a_stopped_child_started_goes_with_it(tmp_path):
    """A third-party controller that starts a helper (same process group), a helper in a session of its own
    (setsid), and a launcher script that runs its node without exec: stop() signalled the child's pid only, and
    all three outlived the benchmark (the node still on the run's private domain). Now the child's group gets the
    signals, what it left is killed after a grace, and its log names the pids; a child alone leaves nothing."""
    import shlex
    import sys
    import time

    pids = tmp_path / 'pids'
    script = (
        'import subprocess, sys, time\n'
        'sleeper = [sys.executable, "-c", "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); '
        'time.sleep(300)"]\n'
        'a = subprocess.Popen(sleeper)\n'
        'b = subprocess.Popen(sleeper, start_new_session=True)\n'
        f'open({str(pids)!r}, "w").write(f"{{a.pid}} {{b.pid}}")\n'
        'time.sleep(300)\n'
    )
    wrapper = tmp_path / 'wrap.sh'  # a launcher without exec: bash waits for its child
    wrapper.write_text(f'#!/bin/bash\n{sys.executable} -c {shlex.quote(script)}\n')
    wrapper.chmod(0o755)
    proc = supervisor.NodeProcess('external_controller', None, None, env={}, log_dir=tmp_path, command=[str(wrapper)])
    proc.start()
    deadline = time.monotonic() + 30
    while not (pids.is_file() and pids.read_text()) and time.monotonic() < deadline:
        time.sleep(0.05)
    helper, own_session = map(int, pids.read_text().split())
    alive = lambda pid: pid in supervisor._proc_table()  # noqa: E731 (a zombie is gone)
    assert alive(helper) and alive(own_session)
    proc.stop(timeout_s=5.0)
    deadline = time.monotonic() + 10
    while (alive(helper) or alive(own_session)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive(helper) and not alive(own_session)
    assert 'process(es) it left behind: pids' in proc.log_text()
    alone = supervisor.NodeProcess(
        'alone', None, None, env={}, log_dir=tmp_path, command=[sys.executable, '-c', 'import time; time.sleep(300)']
    )
    alone.start()
    time.sleep(0.5)
    alone.stop()
    assert 'left behind' not in alone.log_text()


def test_a_private_domain_held_by_another_ceco_process_is_never_given_twice(monkeypatch, tmp_path):
    """Two `ceco run`s (or two benchmark workers) started at once: the second gets the next free id, from the first
    one's lock; when the first process is gone (killed: the kernel drops its lock) its id is free again."""
    import subprocess
    import sys

    code = 'from ceco_bringup import supervisor; print(supervisor.reserve_domain_id(77), flush=True); input()'
    import tempfile

    # the lock files of this test in its own directory (TMPDIR): no other ceco process of the machine counts
    monkeypatch.setattr(tempfile, 'tempdir', str(tmp_path))
    env = dict(os.environ, TMPDIR=str(tmp_path))
    other = subprocess.Popen(
        [sys.executable, '-c', code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
    )
    try:
        assert other.stdout.readline().strip() == '77'
        assert supervisor.reserve_domain_id(77) == 78  # held by the other process: the next one
        monkeypatch.setattr(supervisor, 'pick_domain_id', lambda: 77)
        monkeypatch.delenv('CECO_DOMAIN_ID', raising=False)
        assert supervisor.resolve_domain_id(None, 0, {}) == (78, False)  # a private run of `ceco run` too
        monkeypatch.setenv('CECO_DOMAIN_ID', '77')  # an id asked for is used as it is, held or not
        assert supervisor.resolve_domain_id(None, 0, {}) == (77, False)
        assert supervisor.reserve_domain_id(78) == 78  # this process's own earlier id was let go at its next call
        assert oct((tmp_path / 'ceco_domain_77.lock').stat().st_mode & 0o777) == oct(0o666)  # any user may lock it
    finally:
        other.kill()
        other.wait(timeout=30)
    assert supervisor.reserve_domain_id(77) == 77  # the killed process's lock is gone with it
