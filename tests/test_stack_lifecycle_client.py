"""`ceco run`'s lifecycle manager (supervisor.LifecycleClient) against a managed node whose
answers get lost: real DDS between two rclpy participants in this process. The far side is a
stand-in for the network, not for our nodes: it serves the two lifecycle_msgs services and
loses answers on purpose, as Fast DDS does when a server has not matched the client's
response reader yet ("failed to send response (timeout): client will not receive response",
which failed a CI run's `ceco run`: the controller had configured, the manager never heard)."""

from __future__ import annotations

import threading

import pytest

pytestmark = pytest.mark.stack

rclpy = pytest.importorskip('rclpy', reason='stack tests need the sourced ROS 2 workspace')

from test_stack import DdsPeer, _domain, _wait_for  # noqa: E402

from ceco_bringup import supervisor  # noqa: E402


class LossyLifecycleServer:
    """A node's change_state / get_state services (primary states only) that can lose answers.

    ``mode``: 'lose_first_answer' (the first request runs its transition, its answer never
    comes), 'drop_first_request' (the first request is swallowed: no transition, no answer),
    'swallow_every_request', 'refuse' (every request answered success=false, the state unchanged),
    'refuse_after_swallow' (the first request swallowed, the next refused), 'error_finalizes' (the
    transition fails into finalized, its answer lost), 'lose_first_get' (the first get_state answer
    lost), 'normal'. ``gets`` counts the get_state requests.
    """

    TARGET = {
        1: 'inactive',
        3: 'active',
        4: 'inactive',
        2: 'unconfigured',
        5: 'finalized',
        6: 'finalized',
        7: 'finalized',
    }
    """The state each lifecycle_msgs Transition id ends in (configure 1, cleanup 2, ..., active shutdown 7)."""

    def __init__(self, peer: DdsPeer, name: str, mode: str):
        from lifecycle_msgs.srv import ChangeState, GetState
        from rclpy.callback_groups import ReentrantCallbackGroup

        self.state = 'unconfigured'
        self.requests: list[int] = []
        self.gets = 0
        self.mode = mode
        self.release = threading.Event()  # a lost answer is held until the test ends
        group = ReentrantCallbackGroup()  # on the peer's node, spun by its 4-thread executor
        peer.node.create_service(ChangeState, f'/{name}/change_state', self._change, callback_group=group)
        peer.node.create_service(GetState, f'/{name}/get_state', self._get, callback_group=group)

    def _change(self, request, response):
        tid = request.transition.id
        self.requests.append(tid)
        first = len(self.requests) == 1
        if self.mode == 'refuse' or (self.mode == 'refuse_after_swallow' and not first):
            response.success = False
            return response
        if first and self.mode == 'error_finalizes':
            self.state = 'finalized'
            self.release.wait(30.0)
            response.success = False
            return response
        if self.mode == 'swallow_every_request' or (
            first and self.mode in ('drop_first_request', 'refuse_after_swallow')
        ):
            self.release.wait(30.0)
            response.success = False
            return response
        self.state = self.TARGET[tid]
        if first and self.mode == 'lose_first_answer':
            self.release.wait(30.0)
        response.success = True
        return response

    def _get(self, request, response):
        self.gets += 1
        if self.gets == 1 and self.mode == 'lose_first_get':
            self.release.wait(30.0)
        response.current_state.label = self.state
        return response

    def close(self):
        self.release.set()


@pytest.fixture
def pair():
    """A manager-side peer and a server-side peer on one fresh domain."""
    domain = _domain()
    manager, far = DdsPeer(domain, 'lifecycle_manager'), DdsPeer(domain, 'far_side', threads=4)
    servers = []

    def make(mode, name=None):
        name = name or f'lossy_{mode}'
        server = LossyLifecycleServer(far, name, mode)
        servers.append(server)
        client = supervisor.LifecycleClient(manager.node, name)
        _wait_for(lambda: client.wait(0.1), 60, 'the lossy lifecycle services')
        return server, client

    yield make
    for server in servers:
        server.close()
    far.close()
    manager.close()


def test_a_transition_whose_answer_is_lost_is_read_from_the_state(pair):
    """The node configures, its answer never comes: the manager reads 'inactive' and says
    True without asking again (a second configure would be refused by an inactive node)."""
    server, client = pair('lose_first_answer')
    assert client.change('configure', timeout_s=20.0, attempt_s=0.5)
    assert server.state == 'inactive' and server.requests == [1]
    server.release.set()
    assert client.change('activate', timeout_s=20.0, attempt_s=0.5) and server.requests == [1, 3]


def test_a_request_that_never_ran_is_sent_again(pair):
    """The first configure is swallowed (no transition, no answer): the state still reads
    'unconfigured', so the manager sends it again, and the second one runs."""
    server, client = pair('drop_first_request')
    assert client.change('configure', timeout_s=20.0, attempt_s=0.5)
    assert server.state == 'inactive' and server.requests == [1, 1]  # a third configure would be refused


def test_a_refused_transition_is_false_at_once_and_not_retried(pair):
    """An answer success=false is the node's word: False, one request, state unchanged."""
    server, client = pair('refuse')
    assert not client.change('configure', timeout_s=20.0, attempt_s=0.5)
    assert server.requests == [1] and server.state == 'unconfigured'


def test_no_answer_and_no_progress_is_false_after_the_timeout(pair):
    """A node that swallows every request (it answers get_state: 'unconfigured') is a
    failure within the manager's budget, never a hang; each attempt is a fresh request."""
    server, client = pair('swallow_every_request')
    assert not client.change('configure', timeout_s=3.0, attempt_s=0.5)
    assert server.state == 'unconfigured' and len(server.requests) >= 2


def test_a_transition_that_fails_into_another_state_is_false_at_once(pair):
    """The configure's answer is lost and the node ends finalized (an error in it): neither the goal nor the
    start, so False after one read of the state: not another request, not a poll until the deadline."""
    server, client = pair('error_finalizes')
    assert not client.change('configure', timeout_s=20.0, attempt_s=0.5)
    assert server.requests == [1] and server.state == 'finalized' and server.gets <= 2


def test_a_refusal_after_a_resend_is_read_against_the_state(pair):
    """The first configure is swallowed, the resent one refused with the node still unconfigured: False."""
    server, client = pair('refuse_after_swallow')
    assert not client.change('configure', timeout_s=20.0, attempt_s=0.5)
    assert server.requests == [1, 1] and server.state == 'unconfigured'


def test_shutdown_is_sent_when_the_state_read_before_it_is_lost(pair):
    """shutdown reads the state to pick its transition id; that answer is lost: the read takes at most half
    the budget, and the active shutdown (id 7) is still sent and made."""
    server, client = pair('lose_first_get')
    server.state = 'active'
    assert client.change('shutdown', timeout_s=5.0, attempt_s=5.0)
    assert server.requests == [7] and server.state == 'finalized'


def test_a_dead_node_ends_the_wait(pair):
    """alive() false (the node's process exited, a stop signal): no resend, False."""
    server, client = pair('swallow_every_request')
    assert not client.change('configure', timeout_s=60.0, attempt_s=0.5, alive=lambda: not server.requests)
    assert server.requests == [1] and server.gets == 1


def test_call_service_resends_a_repeatable_request_whose_answer_is_lost(pair):
    """supervisor.call_service with attempt_s: the first get_state answer is lost, the request is sent
    again after 0.5 s and the second one's answer returned; without attempt_s the one request's lost
    answer is None after the timeout, never a hang."""
    from lifecycle_msgs.srv import GetState

    server, client = pair('lose_first_get')
    server.state = 'inactive'
    res = supervisor.call_service(client._get, GetState.Request(), 20.0, attempt_s=0.5)
    assert res is not None and res.current_state.label == 'inactive' and server.gets == 2
    server, client = pair('lose_first_get', 'lossy_once')
    assert supervisor.call_service(client._get, GetState.Request(), 1.0) is None and server.gets == 1
