"""ROS-free command-line tools of the tactile driver.

    prisma-tactile-calset --samples 140000 --seed 0 --out calibration.npz [--plot calibration.png]
        synthetic calibration set (push, slide, press-and-roll) for the force estimator
    prisma-tactile-pad-plot --out pad_response.png
        the pad model's response: force sweep with hysteresis, contact location map, shear skew
    prisma-tactile-hub-emulator --link /tmp/ttyPRISMA [--rate 100] [--seconds 0]
        plays the Arduino hub on a pseudo-terminal (scripted contacts through the pad model), so
        `tactile_driver` with backend:=serial port:=/tmp/ttyPRISMA runs without hardware; stops on
        ctrl-C or SIGTERM and removes its link (frames nobody reads are dropped, as an adapter's
        buffer does, so it never waits on the link)
(also: python -m prisma_tactile_driver.cli calset|pad-plot|hub-emulator ...)

Arguments are checked before any work (exit 2 with a one-line message); every file is written
under a temporary name and renamed when complete (an existing one is replaced).
"""
from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np

from prisma_common.atomic import atomic_output
from prisma_common.cli_args import (
    ArgumentParser,
    UserError,
    command,
    image_file,
    non_negative_float,
    non_negative_int,
    output_file,
    positive_float,
    positive_int,
)
from prisma_common.hand import FINGERS
from prisma_hand_sim.calibration import KINDS, CalibrationSet, generate_calibration_set
from prisma_hand_sim.contact_source import ScriptedContactSource
from prisma_hand_sim.pad_model import PadContact, PadModel


def plot_calibration(cal: CalibrationSet, path: Path, seconds: float = 30.0) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(KINDS), 2, figsize=(12, 2.8 * len(KINDS)), sharex="col")
    for row, kind in enumerate(KINDS):
        index = np.flatnonzero(cal.kind == kind)
        if not len(index):
            continue
        first = index[: int(seconds * 100)]
        t = np.arange(len(first)) * 0.01  # trajectories of this kind back to back, at 100 Hz
        axes[row, 0].plot(t, cal.voltages[first])
        axes[row, 0].set_ylabel(f"{kind}\nvoltage [V]")
        for axis, label in enumerate(("Fx", "Fy", "Fz")):
            axes[row, 1].plot(t, cal.wrench[first, axis], label=label)
        axes[row, 1].set_ylabel("force [N]")
        axes[row, 1].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 1].set_xlabel("time [s]")
    axes[0, 0].set_title(f"9 taxel voltages (first {seconds:g} s of each kind)")
    axes[0, 1].set_title("ground-truth force")
    fig.tight_layout()
    with atomic_output(path) as staged:
        fig.savefig(staged, dpi=90)
    plt.close(fig)


def plot_pad_response(path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    model = PadModel(seed=0)
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    # force sweep up and down at the centre: saturation and hysteresis, with noise and quantisation
    forces = np.concatenate([np.linspace(0, 5, 300), np.linspace(5, 0, 300)])
    volts = model.sample_sequence(np.zeros(600), np.zeros(600), forces) * model.params.lsb_volts
    for taxel, label in ((4, "centre taxel 4"), (5, "edge taxel 5"), (8, "corner taxel 8")):
        axes[0].plot(forces[:300], volts[:300, taxel], label=f"{label} loading")
        axes[0].plot(forces[300:], volts[300:, taxel], "--", label=f"{label} unloading")
    axes[0].set_xlabel("normal force [N]")
    axes[0].set_ylabel("voltage [V]")
    axes[0].set_title("centre press: saturation, hysteresis")
    axes[0].legend(fontsize=7)
    # contact location sweep along x (toward the left side) at 2 N
    xs = np.linspace(-7, 7, 141)
    location = np.array([model.noiseless_voltages(PadContact(x, 0.0, 2.0)) for x in xs])
    for taxel in (3, 4, 5):
        axes[1].plot(xs, location[:, taxel], label=f"taxel {taxel}")
    axes[1].plot(xs, 0.7 * location.mean(axis=1), "k--", label="v_t = 0.7 mean")
    axes[1].set_xlabel("contact x [mm] (+x = left side, column 2)")
    axes[1].set_title("2 N contact moving across the middle row")
    axes[1].legend(fontsize=7)
    # shear skew at the centre
    shears = np.linspace(-1.5, 1.5, 61)
    skew = np.array([model.noiseless_voltages(PadContact(0.0, 0.0, 2.0, s, 0.0)) for s in shears])
    for taxel in (3, 4, 5):
        axes[2].plot(shears, skew[:, taxel], label=f"taxel {taxel}")
    axes[2].set_xlabel("shear x [N] at 2 N normal")
    axes[2].set_title("shear skew")
    axes[2].legend(fontsize=7)
    fig.tight_layout()
    with atomic_output(path) as staged:
        fig.savefig(staged, dpi=90)
    plt.close(fig)


@command("prisma-tactile-calset")
def calset_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-tactile-calset",
                            description="Generate a synthetic fingertip calibration set (.npz)")
    parser.add_argument("--samples", type=positive_int, default=140_000)
    parser.add_argument("--seed", type=non_negative_int, default=0)
    parser.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    parser.add_argument("--rate", type=positive_float, default=100.0, help="sample rate [Hz]")
    parser.add_argument("--out", type=output_file(".npz"), required=True, help="calibration set (.npz)")
    parser.add_argument("--plot", type=image_file, help="also write a plot (.png, .pdf, .svg ...) of the first "
                                                        "seconds of each kind")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    cal = generate_calibration_set(args.samples, args.seed, args.kinds, args.rate)
    cal.save(args.out)
    kinds, counts = np.unique(cal.kind, return_counts=True)
    print(f"{len(cal)} samples in {cal.trajectory.max() + 1} trajectories "
          f"({', '.join(f'{k} {c}' for k, c in zip(kinds, counts))}) in {time.perf_counter() - start:.1f} s")
    print(f"Fz 0..{cal.wrench[:, 2].max():.2f} N, |shear| <= {np.abs(cal.wrench[:, :2]).max():.2f} N, "
          f"voltages {cal.voltages.min():.3f}..{cal.voltages.max():.3f} V -> {args.out}")
    if args.plot:
        plot_calibration(cal, args.plot)
        print(f"plot -> {args.plot}")
    return 0


@command("prisma-tactile-pad-plot")
def pad_plot_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-tactile-pad-plot", description="Plot the optical pad model's response")
    parser.add_argument("--out", type=image_file, required=True, help="image file (.png, .pdf, .svg ...)")
    args = parser.parse_args(argv)
    plot_pad_response(args.out)
    print(f"plot -> {args.out}")
    return 0


@command("prisma-tactile-hub-emulator")
def hub_emulator_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-tactile-hub-emulator",
                            description="Emulate the Arduino fingertip hub on a pseudo-terminal")
    parser.add_argument("--link", type=Path, required=True,
                        help="symlink path to create, e.g. /tmp/ttyPRISMA; only an earlier emulator's link "
                             "(a symlink to a /dev/pts/* pseudo-terminal) is replaced there, and on exit the "
                             "link is removed if it is still this run's")
    parser.add_argument("--rate", type=positive_float, default=100.0, help="frames per second")
    parser.add_argument("--seconds", type=non_negative_float, default=0.0,
                        help="stop after this long (0 = run until Ctrl-C)")
    args = parser.parse_args(argv)


    from .protocol import encode_frame
    from .pty_hub import ADAPTER_BUFFER_BYTES, PtyHubPort
    from .sim_backend import SimHubBackend

    if not args.link.parent.is_dir():
        raise UserError(f"--link {args.link}: the directory {args.link.parent} does not exist; "
                        f"create it or choose another path")
    port = PtyHubPort(args.link)
    try:
        where = port.open()
    except FileExistsError as exc:  # a file, directory, device or foreign symlink at the link path
        raise UserError(f"--link {exc}") from None
    except OSError as exc:  # no permission to create the link there
        raise UserError(f"--link {args.link}: {exc.strerror or exc}; choose another path") from None
    stop = threading.Event()
    # SIGTERM (`ros2 launch`, kill) ends the run as ctrl-C does: the link is removed on the way out
    # (a signal handler can only be set from the main thread; the tests also run this in another)
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set()) if in_main else None
    print(f"hub on {where} at {args.rate:g} Hz; Ctrl-C to stop", flush=True)
    sim = SimHubBackend(ScriptedContactSource(), FINGERS)
    period = 1.0 / args.rate
    start = time.monotonic()
    sequence = dropped = 0
    try:
        while not stop.is_set() and (not args.seconds or time.monotonic() - start < args.seconds):
            stamp_ns = int(sequence * period * 1e9)
            [reading] = sim.read(stamp_ns)
            if not port.offer(encode_frame(sequence, reading.counts), ADAPTER_BUFFER_BYTES):
                dropped += 1
            sequence += 1
            stop.wait(max(0.0, start + sequence * period - time.monotonic()))
    except KeyboardInterrupt:
        pass
    finally:
        port.close()
        if in_main:
            signal.signal(signal.SIGTERM, previous)
    print(f"sent {sequence - dropped} frames" + (f"; {dropped} dropped, nobody read them" if dropped else ""))
    return 0


COMMANDS = {"calset": calset_main, "pad-plot": pad_plot_main, "hub-emulator": hub_emulator_main}

if __name__ == "__main__":  # python -m prisma_tactile_driver.cli calset|pad-plot|hub-emulator ...
    if len(sys.argv) < 2 or sys.argv[1] not in COMMANDS:
        sys.exit(f"usage: python -m prisma_tactile_driver.cli {{{'|'.join(COMMANDS)}}} [options]")
    sys.exit(COMMANDS[sys.argv[1]](sys.argv[2:]))
