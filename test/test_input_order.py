"""Per sensor the newest stamp wins: a message stamped before the reading in use (a second publisher,
a bag played out of order) is refused with an out_of_order WARN and changes nothing; the next solve
uses the newer reading. The same rule for JointState and FluidPressure, one copy (InputTracker), so
the replay judges a reordered bag as the node does."""

from __future__ import annotations

from linkage_monitor.mechanics import load_preset
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.findings import Code, Level

T = 10**18   # ns: the stamps and the monitor's clock (receive times) agree
MS = 1_000_000
TOPIC = "/pressure/lift_cap_pressure"


def _monitor() -> tuple[Monitor, list[str], list[float]]:
    mech = load_preset("belarus_1221")
    ref = mech.reference_inputs
    return (Monitor(mech, MonitorConfig.default("belarus_1221", mech)), ["lift_cylinder", "lift_arm_angle"],
            [ref["cylinders"]["lift_cylinder"], ref["angles"]["lift_arm_angle"]])


def test_an_older_pressure_after_a_newer_one_is_not_applied():
    monitor, names, values = _monitor()
    monitor.on_pressure(TOPIC, 12e6 + ATMOSPHERIC_PRESSURE, T, T)
    late = monitor.on_pressure(TOPIC, 3e6 + ATMOSPHERIC_PRESSURE, T - 400 * MS, T + MS)   # 0.4 s older
    assert [f.code for f in late.findings] == [Code.OUT_OF_ORDER] and late.level == Level.WARN
    assert "0.4 s before the reading in use" in late.findings[0].text and "lift_cap_pressure" in late.findings[0].text
    solved = monitor.on_joint_state(names, values, [], T + 10 * MS, T + 10 * MS)
    assert solved.inputs is not None and solved.inputs.pressures["lift_cap_pressure"] == 12e6


def test_an_older_joint_state_is_refused_whole():
    monitor, names, values = _monitor()
    monitor.on_pressure(TOPIC, 9e6 + ATMOSPHERIC_PRESSURE, T, T)
    first = monitor.on_joint_state(names, values, [], T + 20 * MS, T + 20 * MS)
    assert first.inputs is not None
    moved = [values[0] + 0.01, values[1]]
    late = monitor.on_joint_state(names, moved, [], T + 5 * MS, T + 21 * MS)
    assert [f.code for f in late.findings] == [Code.OUT_OF_ORDER] and late.inputs is None
    again = monitor.on_joint_state(names, values, [], T + 30 * MS, T + 30 * MS)
    assert again.inputs is not None and again.inputs.cylinders["lift_cylinder"] == values[0]


def test_equal_stamps_are_not_out_of_order():
    monitor, names, values = _monitor()
    monitor.on_pressure(TOPIC, 9e6 + ATMOSPHERIC_PRESSURE, T, T)
    same = monitor.on_pressure(TOPIC, 9.5e6 + ATMOSPHERIC_PRESSURE, T, T + MS)
    assert not any(f.code is Code.OUT_OF_ORDER for f in same.findings)
