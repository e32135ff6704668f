"""The source gate (monitoring/sources.py) alone, message by message: two sources of one topic are used
by neither while both are heard within the staleness limit, the trusted one is used whatever the others
send, a source silent for the limit is forgotten. Times in ns; the limit 0.5 s as the node's default."""

from __future__ import annotations

from linkage_monitor.monitoring.findings import Code, Level
from linkage_monitor.monitoring.sources import SourceGate

LIMIT = 500_000_000
MS = 1_000_000


def test_a_second_source_stops_both_until_it_has_been_silent_for_the_limit():
    gate = SourceGate({}, "trusted_publishers")
    assert gate.admit("/j", b"a", "/a", 0, LIMIT).used
    second = gate.admit("/j", b"b", "/b", 10 * MS, LIMIT)
    first = gate.admit("/j", b"a", "/a", 20 * MS, LIMIT)
    assert not second.used and not first.used
    assert second.finding is not None and second.finding.code is Code.SENSORS_DISAGREE
    assert second.finding.text == first.finding.text   # one text whichever sent it
    assert "/a and /b both send /j" in second.finding.text and "'/j=/a'" in second.finding.text
    # b last heard at 10 ms: a is refused up to 510 ms, used again after
    assert not gate.admit("/j", b"a", "/a", 510 * MS, LIMIT).used
    assert gate.admit("/j", b"a", "/a", 511 * MS, LIMIT).used
    assert gate.admit("/other", b"b", "/b", 511 * MS, LIMIT).used   # another topic: its own sources
    level, text = gate.report()
    assert level is Level.WARN and "2 from /a on /j, 1 from /b on /j" in text
    assert gate.report() is None   # counted since the last report


def test_the_trusted_source_is_used_and_the_others_counted():
    gate = SourceGate({"/j": "/b"}, "trusted_publishers")
    assert [gate.admit("/j", key, name, t * MS, LIMIT).used for t, (key, name) in
            enumerate([(b"a", "/a"), (b"b", "/b"), (b"a", "/a"), (b"b", "/b"), (b"c", None)])] == [
        False, True, False, True, False]
    assert gate.report() == (Level.OK, "not used, not the source trusted_publishers trusts: 2 from /a on /j, "
                                       "1 from a publisher not yet named in the graph on /j")


def test_a_message_of_an_untold_source_is_used_only_while_one_source_is_heard():
    gate = SourceGate({}, "trusted_publishers")
    assert gate.admit("/j", None, None, 0, LIMIT).used
    assert gate.admit("/j", b"a", "/a", 1 * MS, LIMIT).used
    assert gate.admit("/j", None, None, 2 * MS, LIMIT).used
    gate.admit("/j", b"b", "/b", 3 * MS, LIMIT)
    assert not gate.admit("/j", None, None, 4 * MS, LIMIT).used
