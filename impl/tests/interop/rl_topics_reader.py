#!/usr/bin/env python3
"""Reads RL's own topics with Eclipse Cyclone DDS, through types written from docs/rl.idl.

An independent implementation decoding RL's heartbeats, votes, controller alarms and voted
commands: each type below is docs/rl.idl's struct of the same name, member for member (IDL
`octet` is uint8, `unsigned short` uint16, `unsigned long` uint32, `unsigned long long`
uint64, `boolean` bool, `T x[3]` array[T, 3]; every struct @final, which Cyclone's IdlStruct
is by default).

Contract
    usage: rl_topics_reader.py DOMAIN [--duration SECONDS] [--idl PATH]

    Joins DDS domain DOMAIN and reads `rl/controller_heartbeat` (best effort),
    `rl/vote` and `rl/controller_alarm` (reliable, transient local) and
    `pixy/servo_control_voted` (best effort) for SECONDS (default 10).
    Prints one JSON object per received sample on stdout, one line each, flushed at once:
        {"topic": "heartbeat", "from_id": 1, "incarnation": 7, "phase": 3, "role": 1,
         "strength": 30, "agreed": [[1, 7], [2, 9], [3, 4]], "vote": [[1, 7], [2, 9], [3, 4]],
         "epoch": 1, "provisional": false, "established_strength": 30,
         "took_over_from": [0, 0], "sent_ms": 1234}
        {"topic": "vote", "from_id": 1, "incarnation": 7, "vote": [[1, 7], [2, 9], [3, 4]]}
        {"topic": "alarm", "reporter_id": 1, "reporter_incarnation": 7, "about_id": 3,
         "about_incarnation": null, "reason": 1, "raised": true}
        {"topic": "voted", "from_id": 1, "input": 0, "input_digest": 0, "raw_after": 0,
         "raw_digest": 0, "pan": 500, "tilt": 500, "frequency": 60}
    An assignment is null when its `valid` flag is false. Prints nothing else on stdout.
    Before joining DDS it checks that the types below are PATH's (default: docs/rl.idl of this
    repository), member for member: same names, order, IDL types and keys.
    Exits 0 after SECONDS; 2 on a bad command line; 1 if the types differ from the IDL or DDS
    cannot start (reason on stderr).

    Needs PyPI `cyclonedds==11.0.1` (bundles the Cyclone library).
"""

import argparse
import json
import re
import sys
import time
import typing
from dataclasses import dataclass, fields
from pathlib import Path

from cyclonedds.core import DDSException, ReadCondition, SampleState, ViewState, InstanceState, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.annotations import key
from cyclonedds.idl.types import array, uint8, uint16, uint32, uint64
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

POLL_MS = 100
TAKE_MAX = 64


@dataclass
class HolderSlot(IdlStruct, typename="rl::HolderSlot"):
    id: uint8
    incarnation: uint64


@dataclass
class WireAssignment(IdlStruct, typename="rl::WireAssignment"):
    slots: array[HolderSlot, 3]


@dataclass
class HeartbeatSample(IdlStruct, typename="rl::HeartbeatSample"):
    from_id: uint8
    key("from_id")
    incarnation: uint64
    phase: uint8
    role: uint8
    strength: uint8
    agreed_valid: bool
    agreed: WireAssignment
    vote_valid: bool
    vote: WireAssignment
    epoch: uint32
    provisional: bool
    established_strength: uint8
    took_over_from: HolderSlot
    sent_ms: uint64


@dataclass
class VoteSample(IdlStruct, typename="rl::VoteSample"):
    from_id: uint8
    key("from_id")
    incarnation: uint64
    vote_valid: bool
    vote: WireAssignment


@dataclass
class AlarmSample(IdlStruct, typename="rl::AlarmSample"):
    reporter_id: uint8
    key("reporter_id")
    reporter_incarnation: uint64
    about_id: uint8
    key("about_id")
    about_incarnation_valid: bool
    about_incarnation: uint64
    reason: uint8
    raised: bool


@dataclass
class ServoControl(IdlStruct, typename="ServoControl"):
    pan: uint16
    tilt: uint16
    frequency: uint16


@dataclass
class VotedServoControl(IdlStruct, typename="rl::VotedServoControl"):
    from_id: uint8
    key("from_id")
    input: uint64
    input_digest: uint64
    raw_after: uint64
    raw_digest: uint64
    value: ServoControl


# What each IDL member type is written as here.
IDL_TYPES = {
    "octet": uint8,
    "unsigned short": uint16,
    "unsigned long": uint32,
    "unsigned long long": uint64,
    "boolean": bool,
}
CHECKED = None  # filled below, once the classes exist
MEMBER = re.compile(r"^\s*(@key\s+)?([A-Za-z_][\w ]*?)\s+(\w+)(\[(\d+)\])?\s*;")


def idl_structs(text):
    """Each struct of the IDL: its members as (name, type, array length or None, keyed)."""
    text = re.sub(r"//[^\n]*", "", text)
    structs = {}
    for match in re.finditer(r"struct\s+(\w+)(?:\s*:\s*\w+)?\s*\{(.*?)\};", text, re.S):
        members = []
        for line in match.group(2).splitlines():
            member = MEMBER.match(line)
            if member:
                length = int(member.group(5)) if member.group(5) else None
                members.append((member.group(3), member.group(2).strip(), length, bool(member.group(1))))
        structs[match.group(1)] = members
    return structs


def differences_from_idl(path):
    """How the classes below differ from the IDL at `path`, in words (empty: they match)."""
    structs = idl_structs(Path(path).read_text())
    found = []
    for cls in CHECKED:
        name = cls.__name__
        if name not in structs:
            found.append(f"{name} is not in {path}")
            continue
        hints = typing.get_type_hints(cls, include_extras=True)
        keys = {k for k, v in getattr(cls, "__idl_field_annotations__", {}).items() if "key" in v}
        ours = [(f.name, hints[f.name]) for f in fields(cls)]
        theirs = structs[name]
        if [n for n, _ in ours] != [m[0] for m in theirs]:
            found.append(f"{name}: members {[n for n, _ in ours]}, the IDL {[m[0] for m in theirs]}")
            continue
        for (member, written), (_, idl_type, length, keyed) in zip(ours, theirs):
            element = IDL_TYPES.get(idl_type) or globals().get(idl_type)
            expected = array[element, length] if length else element
            if written != expected:
                found.append(f"{name}.{member}: written {written}, the IDL says {idl_type}")
            if keyed != (member in keys):
                found.append(f"{name}.{member}: keyed here {member in keys}, in the IDL {keyed}")
    return found


CHECKED = [
    HolderSlot,
    WireAssignment,
    HeartbeatSample,
    VoteSample,
    AlarmSample,
    ServoControl,
    VotedServoControl,
]


def assignment(valid, wire):
    if not valid:
        return None
    return [[slot.id, slot.incarnation] for slot in wire.slots]


def heartbeat_line(s):
    return {
        "topic": "heartbeat",
        "from_id": s.from_id,
        "incarnation": s.incarnation,
        "phase": s.phase,
        "role": s.role,
        "strength": s.strength,
        "agreed": assignment(s.agreed_valid, s.agreed),
        "vote": assignment(s.vote_valid, s.vote),
        "epoch": s.epoch,
        "provisional": s.provisional,
        "established_strength": s.established_strength,
        "took_over_from": [s.took_over_from.id, s.took_over_from.incarnation],
        "sent_ms": s.sent_ms,
    }


def vote_line(s):
    return {
        "topic": "vote",
        "from_id": s.from_id,
        "incarnation": s.incarnation,
        "vote": assignment(s.vote_valid, s.vote),
    }


def alarm_line(s):
    return {
        "topic": "alarm",
        "reporter_id": s.reporter_id,
        "reporter_incarnation": s.reporter_incarnation,
        "about_id": s.about_id,
        "about_incarnation": s.about_incarnation if s.about_incarnation_valid else None,
        "reason": s.reason,
        "raised": s.raised,
    }


def voted_line(s):
    return {
        "topic": "voted",
        "from_id": s.from_id,
        "input": s.input,
        "input_digest": s.input_digest,
        "raw_after": s.raw_after,
        "raw_digest": s.raw_digest,
        "pan": s.value.pan,
        "tilt": s.value.tilt,
        "frequency": s.value.frequency,
    }


def parse_args(argv):
    parser = argparse.ArgumentParser(
        description="Print RL's heartbeats, votes, controller alarms and voted commands as JSON lines (Cyclone DDS)."
    )
    parser.add_argument("domain", type=int, help="DDS domain id (0-232)")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds to read (default 10)")
    parser.add_argument(
        "--idl",
        default=str(Path(__file__).resolve().parents[3] / "docs" / "rl.idl"),
        help="the IDL the types must match (default: this repository's docs/rl.idl)",
    )
    args = parser.parse_args(argv)
    if not 0 <= args.domain <= 232:
        parser.error(f"domain {args.domain} is outside 0-232")
    if args.duration <= 0:
        parser.error(f"--duration {args.duration} must be positive")
    return args


def main(argv):
    args = parse_args(argv)
    try:
        differences = differences_from_idl(args.idl)
    except OSError as error:
        print(f"rl_topics_reader: cannot read the IDL: {error}", file=sys.stderr)
        return 1
    if differences:
        print("rl_topics_reader: the types differ from " + args.idl + ":", file=sys.stderr)
        for difference in differences:
            print("  " + difference, file=sys.stderr)
        return 1
    try:
        participant = DomainParticipant(args.domain)
        best_effort = Qos(Policy.Reliability.BestEffort)
        durable = Qos(
            Policy.Reliability.Reliable(duration(milliseconds=100)),
            Policy.Durability.TransientLocal,
            Policy.History.KeepLast(16),
        )
        readers = [
            (DataReader(participant, Topic(participant, "rl/controller_heartbeat", HeartbeatSample), qos=best_effort), heartbeat_line),
            (DataReader(participant, Topic(participant, "rl/vote", VoteSample), qos=durable), vote_line),
            (DataReader(participant, Topic(participant, "rl/controller_alarm", AlarmSample), qos=durable), alarm_line),
            (DataReader(participant, Topic(participant, "pixy/servo_control_voted", VotedServoControl), qos=best_effort), voted_line),
        ]
    except DDSException as error:
        print(f"rl_topics_reader: cannot start DDS: {error}", file=sys.stderr)
        return 1
    waitset = WaitSet(participant)
    conditions = []
    for reader, line in readers:
        condition = ReadCondition(reader, SampleState.NotRead | ViewState.Any | InstanceState.Any)
        waitset.attach(condition)
        conditions.append((reader, condition, line))
    end = time.monotonic() + args.duration
    while True:
        remaining_ms = int((end - time.monotonic()) * 1000)
        if remaining_ms <= 0:
            break
        waitset.wait(duration(milliseconds=min(remaining_ms, POLL_MS)))
        for reader, condition, line in conditions:
            for sample in reader.take(N=TAKE_MAX, condition=condition):
                if not sample.sample_info.valid_data:
                    continue
                sys.stdout.write(json.dumps(line(sample)) + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
