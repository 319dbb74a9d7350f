"""Pure parts of ceco_bringup.supervisor: which ROS_DOMAIN_ID a `ceco run`
uses, namespace names, and how children are started."""

from __future__ import annotations

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
