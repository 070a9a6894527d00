"""One writer to the motors (issue 11, item 3): the rule, cdpr_msgs_py.sole_writer.SoleWriter."""
from __future__ import annotations

import pytest

from cdpr_msgs_py.sole_writer import Endpoint, SoleWriter


CONTROLLER = '/cdpr/controller'
REAL, OTHER, SPOOF = b'\x01' * 16, b'\x02' * 16, b'\x03' * 16


# ---- the rule ---------------------------------------------------------------------------

def pinned_writer() -> SoleWriter:
    writer = SoleWriter(CONTROLLER)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/intruder', OTHER)])
    return writer


def test_the_controller_is_admitted_once_the_graph_shows_it():
    writer = SoleWriter(CONTROLLER)
    assert not writer.admits(REAL), 'nothing is obeyed before the graph names the writer'
    writer.learn([Endpoint('/cdpr/intruder', OTHER)])
    assert writer.pinned is None and not writer.admits(OTHER)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/intruder', OTHER)])
    assert writer.admits(REAL) and not writer.admits(OTHER)


def test_another_writer_is_rejected_counted_and_named():
    writer = pinned_writer()
    assert writer.reject(OTHER) == (f'node /cdpr/intruder (GID {OTHER.hex()})', True)
    assert writer.reject(OTHER) == (f'node /cdpr/intruder (GID {OTHER.hex()})', False)
    assert writer.rejected_writers() == f'node /cdpr/intruder (GID {OTHER.hex()}): 2'


def test_a_writer_the_graph_cannot_name_yet_is_named_by_gid_and_again_once_it_can():
    writer = pinned_writer()
    who, news = writer.reject(SPOOF)
    assert news and SPOOF.hex() in who and 'does not name' in who
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/late', SPOOF)])
    assert writer.reject(SPOOF) == (f'node /cdpr/late (GID {SPOOF.hex()})', True)


def test_a_publisher_whose_node_the_graph_has_not_announced_is_looked_up_again():
    """The graph knows an endpoint before its node's name; the pinned writer then stays."""
    writer = pinned_writer()
    writer.learn([Endpoint(None, REAL), Endpoint(None, SPOOF)])
    assert writer.admits(REAL), 'a writer whose name is not known for a moment is still there'
    assert 'does not name' in writer.reject(SPOOF)[0]
    assert writer.lookup_due(SPOOF, 0.0)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/late', SPOOF)])
    assert writer.reject(SPOOF)[0].startswith('node /cdpr/late')


def test_a_second_node_named_controller_after_the_first_is_rejected():
    writer = pinned_writer()
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint(CONTROLLER, SPOOF)])
    assert writer.admits(REAL) and not writer.admits(SPOOF)
    assert writer.reject(SPOOF)[0] == f'another node named {CONTROLLER} (GID {SPOOF.hex()})'


def test_two_controllers_before_either_is_pinned_are_both_refused():
    writer = SoleWriter(CONTROLLER)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint(CONTROLLER, SPOOF)])
    assert not writer.admits(REAL) and not writer.admits(SPOOF)
    assert '2 publishers belong to nodes named /cdpr/controller' in writer.problem
    writer.learn([Endpoint(CONTROLLER, REAL)])
    assert writer.admits(REAL) and writer.problem == ''


def test_a_restarted_controller_is_obeyed_once_the_old_one_has_left():
    writer = pinned_writer()
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint(CONTROLLER, SPOOF)])
    assert not writer.admits(SPOOF)
    writer.learn([Endpoint(CONTROLLER, SPOOF)])
    assert writer.admits(SPOOF) and not writer.admits(REAL)


def test_the_graph_is_asked_about_an_unknown_writer_at_most_once_per_interval():
    writer = SoleWriter(CONTROLLER, lookup_interval_s=1.0)
    assert writer.lookup_due(REAL, 0.0) and not writer.lookup_due(REAL, 0.5)
    assert writer.lookup_due(REAL, 1.0)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/intruder', OTHER)])
    assert not writer.lookup_due(OTHER, 5.0), 'a named writer needs no second look'


def test_the_writer_must_be_fully_qualified():
    with pytest.raises(ValueError, match='fully qualified'):
        SoleWriter('controller')
