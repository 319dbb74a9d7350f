"""ceco_ros.entry.start: a stop signal while a node's modules still import ends the process with exit 0 and
one line (issue 17 item 9: `ros2 launch` stopped within a second of starting it)."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROS = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize('sig', ['SIGINT', 'SIGTERM'])
def test_a_stop_signal_during_the_import_exits_0_and_says_so(tmp_path, sig):
    # a node module that is stopped while it imports (as a slow import of numpy/rclpy would be)
    (tmp_path / 'slow_node.py').write_text(
        textwrap.dedent(f"""
            import os, signal, time
            os.kill(os.getpid(), signal.{sig})
            time.sleep(5)
            def main():
                return 3
        """)
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROS)]))
    code = 'import sys; from ceco_ros.entry import start; sys.exit(start("slow_node", "slow_node"))'
    done = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    assert f'[slow_node]: stopped ({sig}) while starting: exit 0' in done.stderr
    assert 'Traceback' not in done.stderr and 'KeyboardInterrupt' not in done.stderr


def test_without_a_signal_the_nodes_main_runs(tmp_path):
    (tmp_path / 'quick_node.py').write_text('def main():\n    return 3\n')
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROS)]))
    code = 'import sys; from ceco_ros.entry import start; sys.exit(start("quick_node", "quick_node"))'
    assert subprocess.run([sys.executable, '-c', code], env=env, timeout=30).returncode == 3


def test_a_stop_while_the_node_is_constructed_exits_0_and_says_so(tmp_path):
    """run_node: SIGINT while the node's constructor runs (after rclpy.init) is caught and said too."""
    pytest.importorskip('rclpy', reason='needs the sourced ROS 2 workspace')
    code = textwrap.dedent("""
        import os, signal, sys, time
        from ceco_ros.node_main import run_node

        def factory():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)

        sys.exit(run_node(factory, None, 'slow_ctor'))
    """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROS), os.environ.get('PYTHONPATH', '')]))
    done = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert '[slow_ctor]: stopped (SIGINT) while starting: exit 0' in done.stderr, done.stderr
    assert 'Traceback' not in done.stderr


@pytest.mark.parametrize('sig', ['SIGINT', 'SIGTERM'])
def test_a_stop_while_rclpy_builds_its_executor_exits_0_without_a_traceback(tmp_path, sig):
    """run_node: a stop signal inside Executor.__init__ (a burst of Ctrl-C under `ros2 launch` hit it
    once in CI: the half-built executor's __del__ printed an AttributeError traceback at exit) stops
    the node with exit 0, one line and no traceback."""
    pytest.importorskip('rclpy', reason='needs the sourced ROS 2 workspace')
    code = textwrap.dedent(f"""
        import os, signal, sys, time
        import rclpy
        from rclpy.executors import Executor
        from ceco_ros.node_main import run_node

        built = Executor.__init__
        def stopped_while_built(self, *args, **kwargs):
            print('building the executor', file=sys.stderr, flush=True)
            os.kill(os.getpid(), signal.{sig})
            time.sleep(5)  # the signal's handler raises here, before the executor has its guard conditions
            built(self, *args, **kwargs)
        Executor.__init__ = stopped_while_built

        sys.exit(run_node(lambda: rclpy.create_node('probe_node'), None, 'probe_node'))
    """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROS), os.environ.get('PYTHONPATH', '')]))
    done = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert 'building the executor' in done.stderr, done.stderr
    assert f'[probe_node]: stopped ({sig}): exit 0' in done.stderr, done.stderr
    assert 'Traceback' not in done.stderr and 'Exception ignored' not in done.stderr, done.stderr


def test_a_constructor_that_raises_is_one_error_line_and_exit_1():
    """run_node: an exception other than ValueError from the node factory (rcl could not create the node) is
    one ERROR line naming it, no traceback, no "stopped ... exit 0" line, and status 1 (START_FAILED_EXIT)."""
    pytest.importorskip('rclpy', reason='needs the sourced ROS 2 workspace')
    code = textwrap.dedent("""
        import sys
        from ceco_ros.node_main import run_node

        def factory():
            raise RuntimeError('error creating node: the middleware said no,\\nat all, at /project/src/x.cpp:364')

        sys.exit(run_node(factory, None, 'broken_node'))
    """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROS), os.environ.get('PYTHONPATH', '')]))
    env.pop('ROS_SECURITY_ENABLE', None)
    done = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stderr
    lines = [line for line in done.stderr.splitlines() if '[broken_node]' in line]
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith('[ERROR] '), done.stderr
    assert lines[0].endswith('[broken_node]: could not start: error creating node: the middleware said no, at all')
    assert 'Traceback' not in done.stderr and 'exit 0' not in done.stderr, done.stderr


def test_start_failure_hints_at_the_keystore_only_when_security_is_on(monkeypatch):
    from ceco_ros.node_main import SECURITY_HINT, start_failure

    err = RuntimeError(
        "error creating node: This Fast DDS version doesn't have the security libraries\n"
        'Please compile Fast DDS using the -DSECURITY=ON CMake option, at /project/src/participant.cpp:364, '
        'at /project/src/rcl/node.c:252'
    )
    monkeypatch.delenv('ROS_SECURITY_ENABLE', raising=False)
    assert start_failure(err) == (
        "could not start: error creating node: This Fast DDS version doesn't have the security libraries "
        'Please compile Fast DDS using the -DSECURITY=ON CMake option'
    )
    monkeypatch.setenv('ROS_SECURITY_ENABLE', 'true')
    assert start_failure(err).endswith(f'option ({SECURITY_HINT})')
    assert SECURITY_HINT not in start_failure(RuntimeError('error creating node: no memory'))
    assert start_failure(RuntimeError()) == 'could not start: RuntimeError'
