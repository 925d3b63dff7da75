"""Every console script, given the mistakes a new user makes, fails with exit 2 and one line that
names the bad value, never a traceback, and leaves nothing behind that looks like a finished output.

Each case runs as a subprocess in a fresh working directory (the tools' default output paths land
there), with the shared inputs (a garbage .npz and .mat, bags without the needed topics, an empty
directory posing as a bundle) in a read-only fixture directory. Before and after the run every
file under both is recorded: the run must not add, change or remove anything. The cases fail
before any heavy work; the few that load torch say so.

Every script that writes files is also given outputs that cannot be created, each of its output
options at least once: a path under /proc (a directory nobody can make there, not even root, whom
permission bits do not stop) and a name too long for the file system. Each fails the same way,
naming the path and the reason.

Also: `--help` of every script builds its parser without importing torch, matplotlib, scipy,
h5py or rosbags (what kept it above 5 s), and the console scripts in pyproject.toml are exactly
the ones covered here.
"""
from __future__ import annotations

import hashlib
import os
import re
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from prisma_testing.repo_paths import CONFIG, ROOT

BUNDLE = str(CONFIG / "models" / "cnn2")

SCRIPTS = {
    "prisma-tactile-calset": "prisma_tactile_driver.cli:calset_main",
    "prisma-tactile-pad-plot": "prisma_tactile_driver.cli:pad_plot_main",
    "prisma-tactile-hub-emulator": "prisma_tactile_driver.cli:hub_emulator_main",
    "prisma-sim": "prisma_sim.sim_cli:main",
    "prisma-hand-emulator": "prisma_hand_emulator.emulator_cli:emulator_main",
    "prisma-hand-fault": "prisma_hand_emulator.emulator_cli:fault_main",
    "prisma-doctor": "prisma_bringup.doctor:main",
    "prisma-train-force": "prisma_force_estimator.cli:train_main",
    "prisma-eval-force": "prisma_force_estimator.cli:eval_main",
    "prisma-estimate-bag": "prisma_force_estimator.cli:estimate_bag_main",
    "prisma-manip-scenarios": "prisma_manipulation.scenarios_cli:main",
    "stag-make-dataset": "stag_glove.cli:make_dataset_main",
    "stag-train-classifier": "stag_glove.cli:train_classifier_main",
    "stag-train-weight": "stag_glove.cli:train_weight_main",
    "stag-train-pose": "stag_glove.cli:train_pose_main",
    "stag-glove-correlation": "stag_glove.cli:correlation_main",
    "prisma-teleop-stag-session": "prisma_teleop.cli:stag_session_main",
    "prisma-dataset": "prisma_dataset.cli:main",
    "prisma-policy": "prisma_policy.cli:main",
}
HEAVY = {"torch", "matplotlib", "scipy", "h5py", "rosbags", "sklearn"}
# the scripts that write nothing (they talk to a running emulator, a running hand)
WRITES_NOTHING = {"prisma-hand-fault", "prisma-doctor"}
# outputs that cannot be created: no directory can be made in /proc; a name over 255 bytes
NOPE = "/proc/prisma-no-such-dir"
LONG = "x" * 300


def pyproject_scripts() -> dict[str, str]:
    text = (ROOT / "pyproject.toml").read_text()
    section = text.split("[project.scripts]", 1)[1].split("\n[", 1)[0]
    return dict(re.findall(r'^([\w-]+)\s*=\s*"([^"]+)"', section, re.M))


def test_every_console_script_is_covered():
    assert pyproject_scripts() == SCRIPTS
    assert {case.script for case in CASES} == set(SCRIPTS)


def run(script: str, args: list[str], cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    module, function = SCRIPTS[script].split(":")
    code = f"import sys; from {module} import {function}; sys.exit({function}())"
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    return subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=env)


# ------------------------------------------------------------------------------------------ inputs
@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    from prisma_common.bag import BagWriter
    from prisma_common.typestore import types
    from prisma_tactile_driver.ros_conversions import taxel_frame_to_msg
    from prisma_tactile_driver.taxels import TaxelFrame

    root = tmp_path_factory.mktemp("inputs")
    rng = np.random.default_rng(0)
    (root / "garbage.npz").write_bytes(rng.integers(0, 256, 400, dtype=np.uint8).tobytes())
    (root / "garbage.mat").write_bytes(b"not MATLAB" + rng.integers(0, 256, 400, dtype=np.uint8).tobytes())
    (root / "notes.txt").write_text("a user's notes\n")
    # well-formed files that cannot serve: one calibration sample, one glove frame
    from prisma_hand_sim.calibration import generate_calibration_set
    from stag_glove.dataset import save_mat
    from stag_glove.synthetic import SyntheticConfig, SyntheticGlove

    generate_calibration_set(1, seed=0).save(root / "one_sample.npz")
    glove = SyntheticGlove(SyntheticConfig(n_objects=2, sessions=2, test_sessions=(1,), frames_per_session=4, seed=0))
    save_mat(glove.object_dataset().subset(np.array([0])), root / "one_frame.mat")
    (root / "empty_dir").mkdir()
    broken = root / "broken_bundle"
    broken.mkdir()
    (broken / "metadata.json").write_text((Path(BUNDLE) / "metadata.json").read_text())
    (broken / "model.pt").write_bytes(b"\x00not a TorchScript archive" * 8)
    # a bag with no fingertip topic at all (like prisma-sim's glove bag)
    String = types("std_msgs/msg/String")
    with BagWriter(root / "chatter_bag") as bag:
        for k in range(3):
            bag.write("/chatter", String(data=f"hello {k}"), timestamp_ns=1_000 + k)
    # a calibration recording without the reference F/T topic
    with BagWriter(root / "thumb_only_bag") as bag:
        for k in range(5):
            counts = np.full(9, 1000 + k, dtype=np.uint16)
            frame = TaxelFrame("thumb", 10_000_000 * (k + 1), counts, (counts * 3.3 / 4096).astype(np.float32))
            bag.write("/prisma/thumb/taxels", taxel_frame_to_msg(types, frame, "thumb_pad"))
    # docs/recording.md's action-topics bag as rosbag2 records it (feedback without a message definition)
    from prisma_testing.recorded_bags import action_goals_bag

    action_goals_bag(root / "hand_goals")
    for path in root.rglob("*"):
        path.chmod(path.stat().st_mode & ~0o222)  # the tools must not write here
    yield root
    for path in [root, *root.rglob("*")]:
        path.chmod(path.stat().st_mode | 0o200)


def snapshot(*roots: Path) -> dict[str, tuple]:
    """path -> (kind, content hash / link target) of everything under `roots`."""
    out = {}
    for root in roots:
        for path in [root, *root.rglob("*")]:
            if path.is_symlink():
                out[str(path)] = ("link", os.readlink(path))
            elif path.is_dir():
                out[str(path)] = ("dir",)
            else:
                out[str(path)] = ("file", hashlib.sha256(path.read_bytes()).hexdigest())
    return out


# ------------------------------------------------------------------------------------------- cases
def foreign_dir(name: str) -> Callable[[Path], None]:
    def make(tmp: Path) -> None:
        (tmp / name).mkdir()
        (tmp / name / "thesis.tex").write_text("mine")
    return make


def regular_file(name: str) -> Callable[[Path], None]:
    return lambda tmp: (tmp / name).write_text("mine")


def existing_dir(name: str) -> Callable[[Path], None]:
    return lambda tmp: (tmp / name).mkdir()


def file_in_dir(directory: str, name: str) -> Callable[[Path], None]:
    def make(tmp: Path) -> None:
        (tmp / directory).mkdir()
        (tmp / directory / name).write_text("mine")
    return make


def symlink(name: str, target: str) -> Callable[[Path], None]:
    def make(tmp: Path) -> None:
        (tmp / target).write_text("mine")
        (tmp / name).symlink_to(tmp / target)
    return make


@dataclass
class Case:
    script: str
    args: list[str]
    needles: tuple[str, ...]  # the bad value (and what else the message must name)
    setup: Callable[[Path], None] | None = None
    absent: tuple[str, ...] = ()  # message must not contain these
    loads_torch: bool = False
    unwritable: bool = False  # an output that cannot be created (NOPE or LONG)
    id: str = field(default="")


C = Case
CASES = [
    # prisma-tactile-calset
    C("prisma-tactile-calset", ["--samples", "0", "--out", "cal.npz"], ("--samples", "'0'", ">= 1")),
    C("prisma-tactile-calset", ["--samples", "many", "--out", "cal.npz"], ("--samples", "'many'")),
    C("prisma-tactile-calset", ["--seed", "-1", "--out", "cal.npz"], ("--seed", "'-1'")),
    C("prisma-tactile-calset", ["--rate", "0", "--out", "cal.npz"], ("--rate", "'0'", "> 0")),
    C("prisma-tactile-calset", ["--out", "cal.csv"], ("cal.csv", ".npz")),
    C("prisma-tactile-calset", ["--out", "cal.npz", "--plot", "cal.xyz"], ("cal.xyz", ".png")),
    C("prisma-tactile-calset", ["--kinds", "twist", "--out", "cal.npz"], ("twist",)),
    C("prisma-tactile-calset", ["--out", "notes/cal.npz"], ("notes", "not a directory"), regular_file("notes")),
    # prisma-tactile-pad-plot
    C("prisma-tactile-pad-plot", ["--out", "x.xyz"], ("x.xyz", "'.xyz'", ".png")),
    C("prisma-tactile-pad-plot", ["--out", "plots"], ("plots", "is a directory"), existing_dir("plots")),
    C("prisma-tactile-pad-plot", [], ("--out", "required")),
    # prisma-tactile-hub-emulator: nothing but its own link is replaced
    C("prisma-tactile-hub-emulator", ["--link", "notes.txt", "--seconds", "0.2"], ("notes.txt", "existing file"),
      regular_file("notes.txt")),
    C("prisma-tactile-hub-emulator", ["--link", "ttydir", "--seconds", "0.2"], ("ttydir", "a directory"),
      existing_dir("ttydir")),
    C("prisma-tactile-hub-emulator", ["--link", "ttyUSB0", "--seconds", "0.2"], ("ttyUSB0", "a symlink to"),
      symlink("ttyUSB0", "real_device")),
    C("prisma-tactile-hub-emulator", ["--link", "tty", "--rate", "0"], ("--rate", "'0'")),
    C("prisma-tactile-hub-emulator", ["--link", "tty", "--seconds", "-1"], ("--seconds", "'-1'")),
    C("prisma-tactile-hub-emulator", ["--link", "no_such_dir/tty"], ("no_such_dir", "does not exist")),
    # prisma-hand-emulator: nothing but its own devices is created or replaced
    C("prisma-hand-emulator", ["--dir", "notes.txt", "--seconds", "0.2"], ("notes.txt", "not a directory"),
      regular_file("notes.txt")),
    C("prisma-hand-emulator", ["--dir", "hand", "--seconds", "0.2"], ("hand/hub", "existing file"),
      file_in_dir("hand", "hub")),
    C("prisma-hand-emulator", ["--dir", "hand", "--rate", "0"], ("--rate", "'0'")),
    C("prisma-hand-emulator", ["--dir", "hand", "--world", "juggling"], ("--world", "'juggling'")),
    C("prisma-hand-emulator", ["--dir", "hand", "--linger", "-1"], ("--linger", "'-1'")),
    # prisma-hand-fault
    C("prisma-hand-fault", ["--dir", "nobody", "status"],
      ("no emulated hand at", "nobody/control.sock", "emulator_dir:=DIR` is reached with `prisma-hand-fault --dir")),
    C("prisma-hand-fault", ["--dir", "nobody", "hub-crc", "--frames", "0"], ("--frames", "'0'")),
    C("prisma-hand-fault", ["--dir", "nobody", "servo-error", "--motor", "fingers"], ("--bit", "required")),
    C("prisma-hand-fault", ["--dir", "nobody", "unplug-everything"], ("unplug-everything",)),
    # prisma-doctor: checked before it looks at the graph
    C("prisma-doctor", ["--namespace", "9 bad"], ("--namespace", "'9 bad'", "not a ROS namespace")),
    C("prisma-doctor", ["--timeout", "0"], ("--timeout", "'0'")),
    C("prisma-doctor", ["--timeout", "1"], ("--timeout 1", "at least 3 s")),
    # prisma-sim
    C("prisma-sim", ["--glove-objects", "0"], ("--glove-objects", "'0'")),
    C("prisma-sim", ["--scenarios", "juggling"], ("juggling",)),
    C("prisma-sim", ["--out", "thesis"], ("thesis", "not prisma-sim output", "thesis.tex"), foreign_dir("thesis")),
    C("prisma-sim", ["--out", "notes.txt"], ("notes.txt", "is a file"), regular_file("notes.txt")),
    C("prisma-sim", ["--scenarios", "horizontal", "--bundle", "{data}/empty_dir"],
      ("empty_dir", "model.pt is missing")),
    C("prisma-sim", ["--force-tolerance", "0"], ("--force-tolerance", "'0'")),
    C("prisma-sim", ["--episodes", "3"], ("--episodes 3", "needs --dataset")),
    C("prisma-sim", ["--dataset", "thesis", "--episodes", "2"], ("--dataset", "thesis", "not a LeRobot dataset",
                                                                  "thesis.tex"), foreign_dir("thesis")),
    C("prisma-sim", ["--dataset", "ds", "--episodes", "0"], ("--episodes", "'0'")),
    C("prisma-sim", ["--scenarios", "horizontal", "--bundle", "{data}/broken_bundle"],
      ("broken_bundle", "not a loadable TorchScript file"), loads_torch=True),
    # prisma-train-force: everything is checked before training
    C("prisma-train-force", ["--model", "cnn2", "--val-fraction", "1.5"],
      ("--val-fraction", "'1.5'", "between 0 and 1")),
    C("prisma-train-force", ["--model", "lstm"], ("--model", "'lstm'")),
    C("prisma-train-force", ["--model", "cnn2", "--data", "{data}/garbage.npz"],
      ("garbage.npz", "not a calibration set"), absent=("unsafely", "pickle")),
    C("prisma-train-force", ["--model", "cnn2", "--data", "missing.npz"], ("missing.npz", "no such file")),
    C("prisma-train-force", ["--model", "cnn2", "--data", "{data}/notes.txt"], ("notes.txt", "'synthetic'")),
    C("prisma-train-force", ["--model", "cnn2", "--out", "thesis"], ("--out", "thesis", "not a model bundle"),
      foreign_dir("thesis")),
    C("prisma-train-force", ["--model", "cnn2", "--out", "notes.txt"], ("--out", "notes.txt", "is a file"),
      regular_file("notes.txt")),
    C("prisma-train-force", ["--model", "cnn2", "--data", "{data}/thumb_only_bag"],
      ("'/ft_sensor/wrench'", "/prisma/thumb/taxels (prisma_msgs/msg/TaxelArray)", "--reference-topic")),
    C("prisma-train-force", ["--model", "cnn2", "--data", "{data}/chatter_bag", "--finger", "index"],
      ("'/prisma/index/taxels'", "'/ft_sensor/wrench'", "/chatter")),
    C("prisma-train-force", ["--model", "cnn2", "--data", "{data}/one_sample.npz"],
      ("one_sample.npz", "at least 2 samples"), loads_torch=True),
    C("prisma-train-force", ["--model", "cnn2", "--epochs", "0"], ("--epochs", "'0'")),
    C("prisma-train-force", ["--model", "cnn2", "--ema-decay", "1"], ("--ema-decay", "'1'")),
    C("prisma-train-force", ["--model", "cnn2", "--lr", "-0.1"], ("--lr", "'-0.1'")),
    C("prisma-train-force", ["--model", "cnn2", "--loss-weights", "tz:0.25"], ("'tz:0.25'", "AXIS=WEIGHT")),
    # prisma-eval-force
    C("prisma-eval-force", [BUNDLE, "--push-samples", "0"], ("--push-samples", "'0'")),
    C("prisma-eval-force", ["{data}/empty_dir"], ("empty_dir", "model.pt is missing")),
    C("prisma-eval-force", ["no_such_bundle_dir"], ("no_such_bundle_dir", "does not exist"), loads_torch=True),
    C("prisma-eval-force", [BUNDLE, "--prefix", "a/b"], ("--prefix", "'a/b'")),
    C("prisma-eval-force", [BUNDLE, "--plots", "notes.txt"], ("--plots", "notes.txt", "is a file"),
      regular_file("notes.txt")),
    C("prisma-eval-force", [BUNDLE, "--table", "tables"], ("--table", "tables", "is a directory"),
      existing_dir("tables")),
    C("prisma-eval-force", ["{data}/broken_bundle", "--push-samples", "10"],
      ("broken_bundle", "not a loadable TorchScript file"), loads_torch=True),
    # prisma-estimate-bag
    C("prisma-estimate-bag", ["{data}/chatter_bag", "out_bag"],
      ("'/prisma/thumb/taxels'", "'/prisma/little/taxels'", "it has: /chatter (std_msgs/msg/String)", "--fingers")),
    C("prisma-estimate-bag", ["{data}/thumb_only_bag", "out_bag", "--fingers", "thumb,index"],
      ("'/prisma/index/taxels'", "/prisma/thumb/taxels (prisma_msgs/msg/TaxelArray)"),
      absent=("'/prisma/thumb/taxels'",)),
    C("prisma-estimate-bag", ["{data}/chatter_bag", "out_bag", "--threads", "0"], ("--threads", "'0'")),
    C("prisma-estimate-bag", ["{data}/empty_dir", "out_bag"], ("empty_dir", "not a readable ROS 2 bag")),
    C("prisma-estimate-bag", ["{data}/hand_goals", "out_bag"],
      ("hand_goals holds topics recorded without a message definition", "/prisma/grasp/_action/feedback",
       "record action topics into a bag of their own")),
    C("prisma-estimate-bag", ["{data}/thumb_only_bag", "notes.txt"], ("notes.txt", "already exists"),
      regular_file("notes.txt")),
    C("prisma-estimate-bag", ["{data}/thumb_only_bag", "out_bag", "--fingers", "thumb,pinky"], ("pinky",)),
    C("prisma-estimate-bag", ["{data}/thumb_only_bag", "out_bag", "--override", "pinky=x"], ("'pinky=x'",)),
    C("prisma-estimate-bag", ["{data}/thumb_only_bag", "out_bag", "--taxel-topic", "/prisma/{fnger}/taxels"],
      ("--taxel-topic", "{fnger}")),
    C("prisma-estimate-bag", ["{data}/notes.txt", "out_bag"], ("notes.txt", "not a bag")),
    C("prisma-estimate-bag", ["{data}/thumb_only_bag", "out_bag", "--bundle", "{data}/empty_dir"],
      ("empty_dir", "model.pt is missing")),
    # prisma-manip-scenarios
    C("prisma-manip-scenarios", ["--bundle", "{data}/empty_dir", "--only", "horizontal"],
      ("empty_dir", "model.pt is missing")),
    C("prisma-manip-scenarios", ["--only", "juggling"], ("juggling",)),
    C("prisma-manip-scenarios", ["--out", "notes.txt"], ("--out", "notes.txt", "is a file"),
      regular_file("notes.txt")),
    # stag-make-dataset
    C("stag-make-dataset", ["glove.txt"], ("glove.txt", ".mat")),
    C("stag-make-dataset", ["glove.mat", "--seed", "-3"], ("--seed", "'-3'")),
    C("stag-make-dataset", ["glove.mat", "--kind", "shoe"], ("'shoe'",)),
    # stag-train-classifier
    C("stag-train-classifier", ["--frames", "0-2"], ("--frames", "'0-2'")),
    C("stag-train-classifier", ["--frames", "a-b"], ("--frames", "'a-b'")),
    C("stag-train-classifier", ["--frames", "1-3", "--bundle-out", "b", "--bundle-frames", "9"],
      ("--bundle-frames 9", "not trained")),
    C("stag-train-classifier", ["--curve-png", "curve.xyz"], ("--curve-png", "curve.xyz")),
    C("stag-train-classifier", ["--seeds", "-1"], ("--seeds", "'-1'")),
    C("stag-train-classifier", ["--dataset", "{data}/garbage.mat"], ("--dataset", "garbage.mat")),
    # stag-train-weight
    C("stag-train-weight", ["--folds", "abc"], ("--folds", "'abc'", "'all'")),
    C("stag-train-weight", ["--folds", "0"], ("--folds", "'0'")),
    C("stag-train-weight", ["--bundle-out", "thesis"], ("--bundle-out", "thesis", "not a model bundle"),
      foreign_dir("thesis")),
    C("stag-train-weight", ["--dataset", "{data}/garbage.mat"], ("--dataset", "garbage.mat", "metadata.mat")),
    C("stag-train-weight", ["--dataset", "{data}/one_frame.mat"], ("one_frame.mat", "1 object(s)", "at least 2")),
    # stag-train-pose
    C("stag-train-pose", ["--dataset", "missing.mat"], ("--dataset", "missing.mat", "no such file")),
    C("stag-train-pose", ["--width", "0"], ("--width", "'0'")),
    C("stag-train-pose", ["--dataset", "{data}/one_frame.mat"], ("one_frame.mat", "both splits", "has 1 and 0")),
    C("stag-train-pose", ["--confusion-png", "conf.txt"], ("--confusion-png", "conf.txt")),
    C("stag-train-pose", ["--dataset", "{data}/empty_dir"], ("--dataset", "empty_dir", "is a directory")),
    C("stag-train-pose", ["--bundle-out", "notes.txt"], ("--bundle-out", "notes.txt", "is a file"),
      regular_file("notes.txt")),
    # stag-glove-correlation
    C("stag-glove-correlation", ["--png", "corr.xyz"], ("--png", "corr.xyz")),
    C("stag-glove-correlation", ["--threads", "0"], ("--threads", "'0'")),
    C("stag-glove-correlation", ["--dataset", "{data}/garbage.mat"], ("--dataset", "garbage.mat")),
    C("stag-glove-correlation", ["--dataset", "{data}/one_frame.mat"], ("one_frame.mat", "1 frame(s)")),
    # prisma-teleop-stag-session
    C("prisma-teleop-stag-session", ["poses.csv"], ("poses.csv", ".h5")),
    C("prisma-teleop-stag-session", ["poses.h5", "--seed", "-2"], ("--seed", "'-2'")),
    C("prisma-teleop-stag-session", ["notes/poses.h5"], ("notes", "not a directory"), regular_file("notes")),
    # prisma-dataset
    C("prisma-dataset", ["export", "{data}/chatter_bag", "--whole-bag", "--out", "ds"],
      ("chatter_bag", "'/joint_states'", "'/prisma/thumb/taxels'", "'/prisma/teleop/motor_targets'",
       "--action positions", "it has: /chatter")),
    C("prisma-dataset", ["export", "{data}/thumb_only_bag", "--out", "ds"], ("has no episode markers", "--whole-bag")),
    C("prisma-dataset", ["export", "{data}/thumb_only_bag", "--whole-bag", "--out", "ds", "--fps", "0"],
      ("--fps", "'0'")),
    C("prisma-dataset", ["export", "{data}/empty_dir", "--whole-bag", "--out", "ds"],
      ("empty_dir", "not a readable ROS 2 bag")),
    C("prisma-dataset", ["export", "no_such_bag", "--whole-bag", "--out", "ds"], ("no_such_bag", "no such file")),
    C("prisma-dataset", ["export", "{data}/thumb_only_bag", "--whole-bag", "--out", "thesis"],
      ("--out", "thesis", "not a LeRobot dataset", "thesis.tex"), foreign_dir("thesis")),
    C("prisma-dataset", ["export", "{data}/thumb_only_bag", "--whole-bag", "--out", "ds", "--append"],
      ("--append", "no dataset there")),
    C("prisma-dataset", ["export", "{data}/thumb_only_bag", "--whole-bag", "--out", "ds", "--action", "guess"],
      ("--action", "'guess'")),
    C("prisma-dataset", ["show", "{data}/empty_dir"], ("empty_dir", "not a LeRobot dataset (no meta/info.json)")),
    C("prisma-dataset", ["show", "no_such_dataset"], ("no_such_dataset", "no such directory")),
    # prisma-policy
    C("prisma-policy", ["train", "{data}/empty_dir", "--out", "policy.pt"],
      ("empty_dir", "not a LeRobot dataset (no meta/info.json)")),
    C("prisma-policy", ["train", "no_such_dataset", "--out", "policy.pt"], ("no_such_dataset", "no such directory")),
    C("prisma-policy", ["train", "{data}/empty_dir", "--out", "policy.txt"], ("--out", "policy.txt", ".pt")),
    C("prisma-policy", ["train", "{data}/empty_dir", "--out", "p.pt", "--steps", "0"], ("--steps", "'0'")),
    C("prisma-policy", ["eval", "{data}/notes.txt"], ("notes.txt", "not a prisma-policy model"), loads_torch=True),
    C("prisma-policy", ["eval", "no_such_model.pt"], ("no_such_model.pt",)),
]


def unwritable(script: str, args: list[str], option: str) -> list[Case]:
    """The same command with its `option` output under /proc and with a too long name; `args` holds
    "{out}" where the output goes (a file name with its extension, or a directory)."""
    cases = []
    for out, needles in ((f"{NOPE}/out", (NOPE, "choose another")), (LONG, ("File name too long",))):
        cases.append(C(script, [a.replace("{out}", out) for a in args], (option, *needles), unwritable=True))
    return cases


def _unwritable_cases() -> list[Case]:
    cases = []
    for script, args, option in [
        ("prisma-tactile-calset", ["--samples", "10", "--out", "{out}.npz"], "--out"),
        ("prisma-tactile-calset", ["--samples", "10", "--out", "cal.npz", "--plot", "{out}.png"], "--plot"),
        ("prisma-tactile-pad-plot", ["--out", "{out}.png"], "--out"),
        ("prisma-tactile-hub-emulator", ["--link", "{out}", "--seconds", "0.2"], "--link"),
        ("prisma-hand-emulator", ["--dir", "{out}", "--seconds", "0.2"], "--dir"),
        ("prisma-sim", ["--out", "{out}"], "--out"),
        ("prisma-train-force", ["--model", "cnn2", "--out", "{out}"], "--out"),
        ("prisma-eval-force", [BUNDLE, "--plots", "{out}"], "--plots"),
        ("prisma-eval-force", [BUNDLE, "--table", "{out}.md"], "--table"),
        ("prisma-eval-force", [BUNDLE, "--json", "{out}.json"], "--json"),
        ("prisma-estimate-bag", ["{data}/thumb_only_bag", "{out}"], "output"),
        ("prisma-manip-scenarios", ["--out", "{out}"], "--out"),
        ("stag-make-dataset", ["{out}.mat"], "out"),
        ("stag-train-classifier", ["--curve-png", "{out}.png"], "--curve-png"),
        ("stag-train-classifier", ["--confusion-png", "{out}.png"], "--confusion-png"),
        ("stag-train-classifier", ["--bundle-out", "{out}"], "--bundle-out"),
        ("stag-train-classifier", ["--out-json", "{out}.json"], "--out-json"),
        ("stag-train-weight", ["--png", "{out}.png"], "--png"),
        ("stag-train-weight", ["--bundle-out", "{out}"], "--bundle-out"),
        ("stag-train-pose", ["--confusion-png", "{out}.png"], "--confusion-png"),
        ("stag-train-pose", ["--bundle-out", "{out}"], "--bundle-out"),
        ("stag-glove-correlation", ["--png", "{out}.png"], "--png"),
        ("prisma-teleop-stag-session", ["{out}.h5"], "out"),
        ("prisma-dataset", ["export", "{data}/thumb_only_bag", "--whole-bag", "--out", "{out}"], "--out"),
        ("prisma-sim", ["--dataset", "{out}"], "--dataset"),
        ("prisma-policy", ["train", "{data}/empty_dir", "--out", "{out}.pt"], "--out"),
        ("prisma-policy", ["eval", "{data}/notes.txt", "--plot", "{out}.png"], "--plot"),
    ]:
        cases += unwritable(script, args, option)
    return cases


CASES += _unwritable_cases()
for _i, _case in enumerate(CASES):
    _case.id = f"{_i:02d}-{_case.script}"


@dataclass
class Outcome:
    result: subprocess.CompletedProcess
    before: dict
    after: dict


@pytest.fixture(scope="module")
def outcomes(data: Path, tmp_path_factory) -> dict[str, Outcome]:
    """Every case, run side by side (one subprocess per core): the corpus is dozens of interpreter
    starts, and the machine has more than one core."""

    def one(case: Case) -> Outcome:
        cwd = tmp_path_factory.mktemp(case.id)
        if case.setup:
            case.setup(cwd)
        before = snapshot(cwd, data)
        result = run(case.script, [a.replace("{data}", str(data)) for a in case.args], cwd)
        return Outcome(result, before, snapshot(cwd, data))

    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2)) as pool:
        return dict(zip([c.id for c in CASES], pool.map(one, CASES)))


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_fails_with_one_line_and_writes_nothing(case: Case, outcomes: dict[str, Outcome], data: Path):
    outcome = outcomes[case.id]
    result = outcome.result
    output = result.stdout + result.stderr
    assert result.returncode == 2, output
    assert "Traceback" not in output
    assert result.stdout == ""  # failed before any work that reports progress
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    # a subcommand's parser names itself too: "prisma-hand-fault servo-error: error: ..."
    assert len(lines) == 1 and re.match(rf"{case.script}( [\w-]+)?: error: ", lines[0]), result.stderr
    for needle in case.needles:
        assert needle in lines[0], (needle, lines[0])
    for text in case.absent:
        assert text not in lines[0], (text, lines[0])
    assert outcome.after == outcome.before, "the failed run changed files"


def test_every_script_that_writes_files_is_given_outputs_it_cannot_create():
    assert {c.script for c in CASES if c.unwritable} == set(SCRIPTS) - WRITES_NOTHING
    for kind in (NOPE, LONG):
        assert {c.script for c in CASES if c.unwritable and any(kind in a for a in c.args)} == \
            set(SCRIPTS) - WRITES_NOTHING


def test_the_corpus_is_large_and_mostly_light():
    assert len(CASES) >= 40
    assert sum(c.loads_torch for c in CASES) <= 5


# ----------------------------------------------------------------------------------------- --help
@pytest.mark.parametrize("script", sorted(SCRIPTS))
def test_help_does_not_import_the_heavy_libraries(script, tmp_path):
    module, function = SCRIPTS[script].split(":")
    code = (f"import sys\nfrom {module} import {function}\n"
            f"try:\n    {function}(['--help'])\nexcept SystemExit as exc:\n    code = exc.code\n"
            f"print('exit', code)\n"
            f"print('heavy', sorted({{m.split('.')[0] for m in sys.modules}} & set({sorted(HEAVY)!r})))\n")
    result = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert "usage:" in result.stdout and "exit 0" in result.stdout
    assert result.stdout.rstrip().endswith("heavy []"), result.stdout[-300:]


def test_model_choices_match_the_networks():
    from prisma_force_estimator.cli import MODEL_CHOICES
    from prisma_force_estimator.networks import MODEL_KINDS

    assert MODEL_CHOICES == MODEL_KINDS
