"""Benchmark of the recorder's bag writer: what a segment close and a recorded second cost;
prints figures, asserts nothing.

1. Rewriting ``metadata.yaml`` at a segment close, when the bag already lists N files:
   PyYAML's dump of the whole mapping against :func:`tail_beam_sim.bags.write.metadata_text`
   (each file's lines rendered once): ms per rewrite and their ratio. A recording of an hour in
   1 s segments lists 3600 files.
2. ``SegmentedBagWriter`` fed one support's shipped-layout traffic (jack pressure and IMU at
   2 kHz, the accelerometer in 200 blocks of 128 samples a second, flushed every 0.2 s as the
   recorder does), closing a segment every ``segment_s`` of data: CPU ms per recorded second.

Usage: python test/bench/bench_bag_segments.py [--repeats 5] [--seconds 20]
Each figure is a median of repeated runs.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

import yaml
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure, Imu, LaserScan

from tail_beam_sim import topics
from tail_beam_sim.bags.write import SegmentedBagWriter, empty_info, metadata_text

SENSOR_RATE_HZ = 2000  # jack pressure and IMU, the shipped layout
BLOCKS_PER_S = 200  # 25.6 kHz accelerometer in blocks of 128 samples
FLUSH_EVERY_S = 0.2  # recorder.flush_s


def listing(files: int) -> dict:
    """A bag's metadata listing ``files`` one-second files of 4200 messages."""
    info = empty_info("mcap")
    info["files"] = [
        {
            "path": f"run_{i:05d}.mcap",
            "starting_time": {"nanoseconds_since_epoch": i * 10**9},
            "duration": {"nanoseconds": 10**9},
            "message_count": 4200,
        }
        for i in range(files)
    ]
    info["relative_file_paths"] = [f["path"] for f in info["files"]]
    return info


def median_ms(work, repeats: int) -> float:
    """Median wall ms of ``work()`` over ``repeats`` runs."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        work()
        times.append((time.perf_counter() - start) * 1e3)
    return statistics.median(times)


def record(seconds: int, segment_s: float) -> float:
    """CPU ms per recorded second of one support's traffic, closing every ``segment_s``."""
    imu, pressure = serialize_message(Imu()), serialize_message(FluidPressure())
    block = serialize_message(LaserScan(ranges=[0.0] * 128))
    per_flush = int(SENSOR_RATE_HZ * FLUSH_EVERY_S)
    flushes_per_segment = max(1, round(segment_s / FLUSH_EVERY_S))
    with tempfile.TemporaryDirectory() as tmp:
        writer = SegmentedBagWriter(f"{tmp}/bag")
        start = time.process_time()
        step_ns = 10**9 // SENSOR_RATE_HZ
        flushes = int(seconds / FLUSH_EVERY_S)
        for f in range(flushes):
            for i in range(per_flush):
                t_ns = (f * per_flush + i) * step_ns
                writer.write(topics.JACK_PRESSURE, t_ns, pressure)
                writer.write(topics.IMU, t_ns, imu)
                if i % (SENSOR_RATE_HZ // BLOCKS_PER_S) == 0:
                    writer.write(topics.VIBRATION, t_ns, block)
            writer.flush()
            if (f + 1) % flushes_per_segment == 0:
                writer.close_segment()
        writer.close()
        return (time.process_time() - start) * 1e3 / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seconds", type=int, default=20)
    args = parser.parse_args()
    print("metadata.yaml rewrite at a segment close (median ms)")
    print(f"{'files':>6} {'yaml.dump':>10} {'metadata_text':>14} {'ratio':>6}")
    for files in (10, 360, 3600):
        info = listing(files)
        dumped = median_ms(
            lambda i=info: yaml.dump(
                {"rosbag2_bagfile_information": i}, Dumper=yaml.CSafeDumper, sort_keys=False
            ),
            args.repeats,
        )
        rendered = median_ms(lambda i=info: metadata_text(i), args.repeats)
        print(f"{files:>6} {dumped:>10.2f} {rendered:>14.2f} {dumped / rendered:>6.1f}")
    print(f"\nSegmentedBagWriter, one support's shipped traffic, {args.seconds} s recorded")
    print(f"{'segment_s':>9} {'CPU ms per recorded s (median)':>31}")
    for segment_s in (1.0, 5.0):
        cpu = statistics.median(record(args.seconds, segment_s) for _ in range(args.repeats))
        print(f"{segment_s:>9g} {cpu:>31.1f}")


if __name__ == "__main__":
    main()
