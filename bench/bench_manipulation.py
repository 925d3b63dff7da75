"""Manipulation benchmarks (python bench/run.py --only control_step).

- control_step: Algorithm 1 for all five fingers + one controller step, per second, single thread;
  the hand samples at 100 Hz, so 100 steps/s are needed.
- dynamixel_cycle: one motor-driver cycle over dynamixel-sdk (sync read 126..135 + sync read of
  Hardware Error Status + sync write of goal velocities) against the pty servo emulator, per second;
  /joint_states needs 100 Hz. The pty and the emulator thread, not a 1 Mbaud wire, bound this figure.
- hand_sim_step: one closed-loop sample of the simulation (sim motors + hand/world + five PadModels +
  monitor + controller) per second; the ROS sim needs 100 Hz.
"""
from __future__ import annotations

import time

import numpy as np

from prisma_common.hand import FINGERS, MOTOR_NAMES
from prisma_manipulation.contact_monitor import DEFAULT_K, ContactMonitor
from prisma_manipulation.controllers import ControlInput, ControlLimits, JointSample
from prisma_manipulation.motion_controllers import HoldController
from prisma_manipulation.scenarios import build
from prisma_motor_driver.backend import default_motors
from run import Benchmark

MIN_SECONDS = 1.0


def _recorded_inputs():
    """Voltages, forces and joints of the disturbance scenario: edges get lost and restored, so
    the timed steps take every branch, not only the idle one."""
    sc = build("disturbance")
    trace = sc.run()
    return (trace.array("voltages"), trace.array("forces_true"), trace.array("positions"),
            np.asarray(trace.stamps_ns))


def _measure_control_step(bench: Benchmark) -> float:
    volts, forces, positions, stamps = _recorded_inputs()
    monitor = ContactMonitor(DEFAULT_K)
    samples = [
        (int(stamps[i]), [volts[i, f] for f in range(len(FINGERS))], dict(zip(FINGERS, forces[i].tolist())),
         JointSample(int(stamps[i]), dict(zip(MOTOR_NAMES, positions[i].tolist()))))
        for i in range(len(stamps))
    ]

    def fresh():
        c = HoldController(ControlLimits(default_motors()), 20.0, timeout_s=3.0)  # the disturbance goal's
        c.start(samples[0][3])
        return c

    controller = fresh()
    latencies = []
    steps = 0
    start = time.perf_counter()
    while True:
        for stamp, v, f, joints in samples:
            t0 = time.perf_counter_ns()
            contacts = {finger: monitor.evaluate(finger, stamp, v[i]) for i, finger in enumerate(FINGERS)}
            controller.step(ControlInput(stamp, contacts, f, joints))
            latencies.append(time.perf_counter_ns() - t0)
            steps += 1
        controller = fresh()
        elapsed = time.perf_counter() - start
        if elapsed >= MIN_SECONDS:
            break
    lat = np.asarray(latencies) / 1e3
    bench.notes.update(p50_us=round(float(np.percentile(lat, 50)), 1), p99_us=round(float(np.percentile(lat, 99)), 1),
                       steps=steps)
    return steps / elapsed


def _measure_dynamixel_cycle(bench: Benchmark) -> float:
    from prisma_motor_driver.backend import default_motors
    from prisma_motor_driver.dynamixel_backend import DynamixelBus
    from prisma_motor_driver.dynamixel_emulator import DynamixelEmulator

    with DynamixelEmulator([1, 2, 3]) as emu:
        bus = DynamixelBus(emu.port_name, 1_000_000, default_motors())
        bus.open()
        latencies = []
        cycles = 0
        start = time.perf_counter()
        while time.perf_counter() - start < MIN_SECONDS:
            t0 = time.perf_counter_ns()
            bus.read_state()
            bus.set_velocities({"fingers": 10.0, "thumb_flexion": -10.0, "thumb_rotation": 0.0})
            latencies.append(time.perf_counter_ns() - t0)
            cycles += 1
        elapsed = time.perf_counter() - start
        bus.close()
    lat = np.asarray(latencies) / 1e3
    bench.notes.update(p50_us=round(float(np.percentile(lat, 50)), 1), p99_us=round(float(np.percentile(lat, 99)), 1),
                       retries=bus.stats.retries)
    return cycles / elapsed


def _measure_hand_sim_step(bench: Benchmark) -> float:
    samples = 0
    start = time.perf_counter()
    while time.perf_counter() - start < MIN_SECONDS:
        sc = build("vertical")
        trace = sc.run()
        samples += len(trace.stamps_ns)
    elapsed = time.perf_counter() - start
    bench.notes.update(samples=samples)
    return samples / elapsed


control_step = Benchmark("control_step", lambda: _measure_control_step(control_step), "steps/s", 100.0)
dynamixel_cycle = Benchmark("dynamixel_cycle", lambda: _measure_dynamixel_cycle(dynamixel_cycle), "cycles/s", 100.0)
hand_sim_step = Benchmark("hand_sim_step", lambda: _measure_hand_sim_step(hand_sim_step), "samples/s", 100.0)

BENCHMARKS = [control_step, dynamixel_cycle, hand_sim_step]
