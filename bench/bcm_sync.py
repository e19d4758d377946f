#!/usr/bin/env python3
"""A SYNC producer on the kernel's broadcast manager (CAN_BCM), for bench/sync_jitter.sh.

One TX_SETUP with SETTIMER|STARTTIMER, count 0, ival2 = the period: from then on the kernel sends
080h (no data) every period from an hrtimer, whatever this process does. It then waits for SIGTERM
or SIGINT (or --duration) and exits; closing the socket deletes the job (the script checks that the
SYNC stops with the process).
  bench/bcm_sync.py --interface vcan0 --period-us 20000 [--duration S]
"""
import argparse
import signal
import socket
import struct
import sys
import time

# struct bcm_msg_head: opcode, flags, count, ival1 {sec, usec}, ival2 {sec, usec}, can_id, nframes;
# native alignment puts the padding after count (struct bcm_timeval holds longs) as the kernel does.
BCM_HEAD = "@3I4l2I0q"
CAN_FRAME = "=IB3x8s"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--interface", default="vcan0")
    p.add_argument("--period-us", type=int, default=20000)
    p.add_argument("--duration", type=float, default=0, help="seconds, 0: until SIGTERM")
    a = p.parse_args()

    s = socket.socket(socket.AF_CAN, socket.SOCK_DGRAM, socket.CAN_BCM)
    s.connect((a.interface,))
    flags = socket.CAN_BCM_SETTIMER | socket.CAN_BCM_STARTTIMER
    head = struct.pack(BCM_HEAD, socket.CAN_BCM_TX_SETUP, flags, 0, 0, 0,
                       a.period_us // 1_000_000, a.period_us % 1_000_000, 0x080, 1)
    s.send(head + struct.pack(CAN_FRAME, 0x080, 0, b""))
    print(f"bcm_sync: TX_SETUP 080h every {a.period_us} us on {a.interface}", flush=True)

    stop = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.append(1))
    end = time.monotonic() + a.duration if a.duration > 0 else None
    while not stop and (end is None or time.monotonic() < end):
        time.sleep(0.2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
