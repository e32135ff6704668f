"""The monitor's verdict on the poses ``solve`` and ``capacity`` compute: each pose's inputs handed to
the monitoring core (:class:`linkage_monitor.monitoring.core.Monitor`) as the input events the live
node's callbacks give it, so the command line says what the node says (level and findings, worded by
the core) and prints the pose the node would publish. Nothing here words a verdict of its own.

Units SI (m, rad, gauge Pa); stamps ns.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Mapping, Sequence

import numpy as np

from linkage_monitor.mechanics import Inputs, Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor, Step
from linkage_monitor.monitoring.events import InputEvent, JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code, Finding, Level

ERROR_EXIT = 1   # the exit code of ``solve`` / ``capacity`` when the monitor's verdict is ERROR
SERIES_PERIOD_NS = 1_000_000   # ns between the stamps of the poses of a series (any period < the staleness limit)


def monitor_for(mech: Mechanism, spec: str, pressures: Sequence[str] = (), uncertainty: bool = False) -> Monitor:
    """The node's monitor of ``mech`` (``spec``: preset name or file, for the record) with its default
    configuration, but reading only the pressure sensors ``pressures`` (gauge Pa, as the CLI takes them):
    a pressure not given is not awaited, the implement load then comes from ``implement.mass``;
    ``uncertainty``: its poses carry their error budget and its limits are judged on their 95 % intervals."""
    default = MonitorConfig.default(spec, mech)
    config = replace(default, pressure_absolute=False, uncertainty=uncertainty,
                     pressure_topics={t: s for t, s in default.pressure_topics.items() if s in pressures})
    return Monitor(mech, config)


def pose_events(monitor: Monitor, inputs: Inputs, stamp_ns: int) -> list[InputEvent]:
    """The input events of one pose, as the node receives them: one FluidPressure per pressure sensor,
    then one JointState of every measured cylinder length and angle (which triggers the solve)."""
    config = monitor.config
    topics = {sensor: topic for topic, sensor in config.pressure_topics.items()}
    events: list[InputEvent] = [PressureEvent(topics[name], value, stamp_ns, stamp_ns)
                                for name, value in inputs.pressures.items()]
    joints = {**inputs.cylinders, **inputs.angles}
    events.append(JointStateEvent(config.topics.joint_states, list(joints), list(joints.values()), [], stamp_ns,
                                  stamp_ns))
    return events


def judge(mech: Mechanism, spec: str, inputs: Inputs, uncertainty: bool = False) -> Step:
    """The monitor's Step of one pose (``inputs``: the measured values, SI units; ``uncertainty`` as
    ``monitor_for``'s). Its findings are those of the pose's own step plus any refusal of the pose's
    earlier messages (a pressure the node refuses): the earlier steps' "no value yet" only says the
    pose was not complete yet."""
    monitor = monitor_for(mech, spec, list(inputs.pressures), uncertainty)
    steps = [monitor.step(event) for event in pose_events(monitor, inputs, time.time_ns())]
    *earlier, last = steps
    refused = tuple(f for step in earlier for f in step.findings if f.code is not Code.NO_VALUE_YET)
    return replace(last, findings=refused + last.findings)


def judge_strokes(mech: Mechanism, spec: str, lengths: Mapping[str, np.ndarray]) -> list[Step]:
    """The monitor's Steps of the poses of a stroke sweep (``lengths``: measured cylinder -> (N,) m,
    ``mech`` measuring only those), solved as the replay solves a recording: each pose from the one before."""
    monitor = monitor_for(mech, spec)
    names = list(lengths)
    values = np.column_stack([np.asarray(lengths[n], dtype=float) for n in names])
    start = time.time_ns()
    events = [JointStateEvent(monitor.config.topics.joint_states, names, row, [], start + k * SERIES_PERIOD_NS,
                              start + k * SERIES_PERIOD_NS) for k, row in enumerate(values.tolist())]
    return list(monitor.run(events).steps)


def worst(steps: Sequence[Step]) -> Level:
    """The worst level of ``steps`` (OK for none)."""
    return max((s.level for s in steps), default=Level.OK)


def exit_code(level: Level) -> int:
    """``ERROR_EXIT`` for an ERROR verdict, 0 for OK and WARN."""
    return ERROR_EXIT if level >= Level.ERROR else 0


def finding_line(finding: Finding) -> str:
    """``LEVEL code: sentence`` (the core's sentence)."""
    return f"{finding.level.name} {finding.code.ident}: {finding.text}"


def finding_json(finding: Finding) -> dict[str, str]:
    """``{"level", "code", "message"}`` of a finding."""
    return {"level": finding.level.name, "code": finding.code.ident, "message": finding.text}
