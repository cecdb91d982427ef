#!/usr/bin/env python3
"""Reads ServoControl commands with Eclipse Cyclone DDS: a second, independent DDS peer.

An interoperability-test peer like connext_reader.py, from another vendor: it shows which
writer a Cyclone reader with EXCLUSIVE ownership follows. Cyclone does not fail over on a
missed deadline while a weaker writer keeps publishing (the weaker writer's samples renew the
instance's deadline); it fails over when the owner's liveliness lease expires, hence the lease.

Contract
    usage: cyclone_reader.py DOMAIN [--duration SECONDS] [--topic NAME] [--deadline-ms MS]
                             [--lease-ms MS]

    Joins DDS domain DOMAIN and reads topic NAME (default `pixy/servo_control`), type
    `ServoControl {uint16 pan, tilt, frequency}`, with QoS: reliable, EXCLUSIVE ownership,
    deadline MS (default 100), automatic liveliness with lease MS (default 300; the writer must
    offer a lease no longer than this to match). The type is declared final: RustDDS and the
    original write plain (XCDR1) CDR, where an appendable struct of three uint16 has the same
    bytes, and Cyclone would insist on XCDR2 for an appendable one.

    Prints one JSON object per received sample on stdout, one line each, flushed at once:
        {"t_ms": 1712345678901.234, "writer_guid": "0102...10", "pan": 500, "tilt": 500,
         "frequency": 60}
    t_ms is the reception time, Unix milliseconds (comparable across processes);
    writer_guid is the writer's 16-byte GUID as 32 lowercase hex digits.
    Prints nothing else on stdout. Exits 0 after SECONDS (default 10), also when no writer
    was seen; exits 2 on a bad command line, 1 if DDS cannot start (reason on stderr).

    Needs PyPI `cyclonedds==11.0.1` (bundles the Cyclone library).
"""

import argparse
import json
import sys
import time
from dataclasses import dataclass

from cyclonedds.core import DDSException, InstanceState, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import uint16
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

# Wake up at least this often to notice the end of the run.
POLL_MS = 100
# Samples taken per wake-up at most; more wait for the next one.
TAKE_MAX = 64


@dataclass
class ServoControl(IdlStruct, typename="ServoControl"):
    pan: uint16
    tilt: uint16
    frequency: uint16


def parse_args(argv):
    parser = argparse.ArgumentParser(description="Print ServoControl samples as JSON lines (Cyclone DDS).")
    parser.add_argument("domain", type=int, help="DDS domain id (0..232)")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds to run (default 10)")
    parser.add_argument("--topic", default="pixy/servo_control", help="topic name")
    parser.add_argument("--deadline-ms", type=int, default=100, help="requested deadline (ms)")
    parser.add_argument("--lease-ms", type=int, default=300, help="requested liveliness lease (ms)")
    args = parser.parse_args(argv)
    if not 0 <= args.domain <= 232:
        parser.error("domain must be 0..232")
    if args.duration < 0 or args.deadline_ms < 1 or args.lease_ms < 1:
        parser.error("duration must be >= 0, deadline-ms and lease-ms >= 1")
    return args


class WriterGuids:
    """Writer GUIDs by publication handle; the handle is all a sample says of its writer."""

    def __init__(self, reader):
        self.reader = reader
        self.by_handle = {}

    def guid_hex(self, handle):
        guid = self.by_handle.get(handle)
        if guid is None:
            try:
                endpoint = self.reader.get_matched_publication_data(handle)
            except DDSException:
                endpoint = None
            if endpoint is None:
                # The writer left before it could be looked up: say so rather than guess.
                return f"unknown-handle-{handle:x}"
            guid = endpoint.key.bytes.hex()
            self.by_handle[handle] = guid
        return guid


def main(argv):
    args = parse_args(argv)
    qos = Qos(
        Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
        Policy.Ownership.Exclusive,
        Policy.Deadline(duration(milliseconds=args.deadline_ms)),
        Policy.Liveliness.Automatic(lease_duration=duration(milliseconds=args.lease_ms)),
    )
    try:
        participant = DomainParticipant(args.domain)
        topic = Topic(participant, args.topic, ServoControl)
        reader = DataReader(participant, topic, qos=qos)
    except DDSException as error:
        print(f"cyclone_reader: cannot start DDS: {error}", file=sys.stderr)
        return 1
    guids = WriterGuids(reader)
    condition = ReadCondition(reader, SampleState.NotRead | ViewState.Any | InstanceState.Any)
    waitset = WaitSet(participant)
    waitset.attach(condition)
    end = time.monotonic() + args.duration
    while True:
        remaining_ms = int((end - time.monotonic()) * 1000)
        if remaining_ms <= 0:
            break
        waitset.wait(duration(milliseconds=min(remaining_ms, POLL_MS)))
        for sample in reader.take(N=TAKE_MAX, condition=condition):
            info = sample.sample_info
            if not info.valid_data:
                continue
            line = {
                "t_ms": round(time.time() * 1000, 3),
                "writer_guid": guids.guid_hex(info.publication_handle),
                "pan": sample.pan,
                "tilt": sample.tilt,
                "frequency": sample.frequency,
            }
            sys.stdout.write(json.dumps(line) + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
