#!/usr/bin/env python3
"""Reads ServoControl commands the way the original camera gimbal does, with RTI Connext.

An independent DDS peer for interoperability tests: it shows which writer a Connext reader
with EXCLUSIVE ownership actually follows, so tests can check RL's strengths and switchover
against a real ownership implementation.

Contract
    usage: connext_reader.py DOMAIN [--duration SECONDS] [--topic NAME] [--deadline-ms MS]
                             [--liveliness-check-ms MS]

    Joins DDS domain DOMAIN and reads topic NAME (default `pixy/servo_control`), type
    `ServoControl {uint16 pan, tilt, frequency}` (appendable, as in the original), with QoS:
    reliable, EXCLUSIVE ownership, deadline MS (default 100), loopback enabled
    (servo_control_connext.xml beside this file declares type and QoS).

    --liveliness-check-ms sets how often, at the longest, the participant checks whether
    a writer's liveliness lease has passed without an assertion (Connext's
    `max_liveliness_loss_detection_period`; default 60000, Connext's own). A writer found
    not alive loses ownership until its next sample: a short period makes a writer whose
    liveliness is not asserted in time show at once, rather than once a minute.

    Prints one JSON object per received sample on stdout, one line each, flushed at once:
        {"t_ms": 1712345678901.834, "rx_ms": 1712345678901.234, "writer_guid": "0102...10",
         "pan": 500, "tilt": 500, "frequency": 60}
    rx_ms is the reception time Connext recorded for the sample and t_ms the time this script
    handled it, both Unix milliseconds (comparable across processes). Judge the reader by
    rx_ms: t_ms adds this Python process's own scheduling (0.2 ms at the median, 10 ms at
    worst on an idle two-core machine, more under load);
    writer_guid is the writer's 16-byte GUID as 32 lowercase hex digits.
    Prints nothing else on stdout. Stops reading after SECONDS (default 10) and exits 0, also
    when no writer was seen; closing the Connext participant adds about 3 s before the exit.
    Exits 2 on a bad command line, 1 if DDS cannot start (reason on stderr).

    Needs PyPI `rticonnextdds-connector==1.2.4` (bundles the Connext libraries; no license).
"""

import argparse
import json
import os
import sys
import time

XML_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), "servo_control_connext.xml")
PARTICIPANT = "RlInteropParticipants::ServoReader"
READER = "Subscriber::Reader"
# Wake up at least this often to notice the end of the run.
POLL_MS = 100


def parse_args(argv):
    parser = argparse.ArgumentParser(description="Print ServoControl samples as JSON lines (Connext).")
    parser.add_argument("domain", type=int, help="DDS domain id (0..232)")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds to run (default 10)")
    parser.add_argument("--topic", default="pixy/servo_control", help="topic name")
    parser.add_argument("--deadline-ms", type=int, default=100, help="requested deadline (ms)")
    parser.add_argument(
        "--liveliness-check-ms",
        type=int,
        default=60000,
        help="longest period between the participant's liveliness checks (ms, default 60000)",
    )
    args = parser.parse_args(argv)
    if not 0 <= args.domain <= 232:
        parser.error("domain must be 0..232")
    if args.duration < 0 or args.deadline_ms < 1 or args.liveliness_check_ms < 1:
        parser.error("duration must be >= 0, deadline-ms and liveliness-check-ms >= 1")
    return args


def guid_hex(identity):
    """The writer GUID from a sample identity: a list of 16 byte values."""
    return bytes(identity["writer_guid"]).hex()


def main(argv):
    args = parse_args(argv)
    # servo_control_connext.xml reads these.
    os.environ["RL_INTEROP_DOMAIN"] = str(args.domain)
    os.environ["RL_INTEROP_TOPIC"] = args.topic
    os.environ["RL_INTEROP_DEADLINE_SEC"] = str(args.deadline_ms // 1000)
    os.environ["RL_INTEROP_DEADLINE_NANOSEC"] = str((args.deadline_ms % 1000) * 1_000_000)
    os.environ["RL_INTEROP_LIVELINESS_CHECK_SEC"] = str(args.liveliness_check_ms // 1000)
    os.environ["RL_INTEROP_LIVELINESS_CHECK_NANOSEC"] = str(
        (args.liveliness_check_ms % 1000) * 1_000_000
    )

    import rticonnextdds_connector as rti

    try:
        connector = rti.Connector(config_name=PARTICIPANT, url=XML_PATH)
    except rti.Error as error:
        print(f"connext_reader: cannot start DDS: {error}", file=sys.stderr)
        return 1
    try:
        reader = connector.get_input(READER)
        end = time.monotonic() + args.duration
        while True:
            remaining_ms = int((end - time.monotonic()) * 1000)
            if remaining_ms <= 0:
                break
            try:
                reader.wait(min(remaining_ms, POLL_MS))
            except rti.TimeoutError:
                continue
            reader.take()
            for sample in reader.samples.valid_data_iter:
                line = {
                    "t_ms": round(time.time() * 1000, 3),
                    "rx_ms": round(sample.info["reception_timestamp"] / 1e6, 3),
                    "writer_guid": guid_hex(sample.info["identity"]),
                    "pan": int(sample.get_number("pan")),
                    "tilt": int(sample.get_number("tilt")),
                    "frequency": int(sample.get_number("frequency")),
                }
                sys.stdout.write(json.dumps(line) + "\n")
            sys.stdout.flush()
    finally:
        connector.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
