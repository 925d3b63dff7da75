"""The paths and commands README.md and docs/*.md show work as written, from the repository root.

The top-level `launch/` and `config/` are links to prisma_bringup's folders (the design card's
layout and the ROS package's both), so the documented `config/...` and `launch/...` paths name the
shipped files from the root:

- every repository path the documents name (`config/...`, `launch/...`, `docs/...`, `src/...`,
  `test/...`, `bench/...`, `firmware/...`, `tools/...`; globs match something, `a|b|c` alternatives
  each, placeholders such as `<node>` skipped) exists;
- the commands that take under a minute and need nothing running run as shown: every
  `ros2 run <package> <node> --ros-args --params-file config/...` line (in the documents and in the
  nodes' docstrings) starts its node from the root, which then stops on ctrl-C with exit 0 and no
  traceback (ROS only); every `prisma-eval-force` line whose bundles are shipped and that writes
  nothing (no --plots, --json, --table) evaluates them (as `python -m prisma_force_estimator.cli
  eval`, the checkout's code: the console script on PATH may be another install's).
- every `ros2 launch prisma_bringup <file> name:=value ...` line (documents and the launch files'
  docstrings) passes arguments that file declares, with a value among its choices where it has any;
- docs/architecture.md's launch-file table names, for each launch file, exactly the arguments it
  declares (an argument added, renamed or dropped shows up here, not in a user's `ros2 launch`);
- README.md stays a front door: at most README_MAX_LINES lines, its links into the handbook resolve,
  and it shows a launch of each kind of hand and one grasp.
The rest (launches, goals, training for minutes, commands on recordings) are run by the launch,
CLI and training tests; here their paths are checked.
"""
from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from prisma_testing.launch_files import declared_arguments
from prisma_testing.node_process import NodeProcess
from prisma_testing.repo_paths import BRINGUP, LAUNCH, ROOT

DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
NODE_MODULES = sorted(p for p in (ROOT / "src").glob("*/*/*_node.py"))
REPOSITORY_PATH = re.compile(r"(?<![\w/.$~-])((?:config|launch|docs|src|test|firmware|bench|tools)/[\w./*<>|{}-]*)")
# named in the documents, not paths of this repository
NOT_THIS_REPOSITORY = {"src/prisma": "the robot workspace's clone of this repository (README, On the robot)"}


README_MAX_LINES = 220  # issue 42: the rest belongs in the handbook (docs/)


def named_paths() -> dict[str, list[str]]:
    """Repository path as written -> where (file:line) the documents name it."""
    found: dict[str, list[str]] = {}
    for document in DOCUMENTS:
        for number, line in enumerate(document.read_text().splitlines(), 1):
            for match in REPOSITORY_PATH.finditer(line):
                path = match.group(1).rstrip(".,;:")
                if "<" in path or "{" in path or path in NOT_THIS_REPOSITORY:
                    continue
                found.setdefault(path, []).append(f"{document.relative_to(ROOT)}:{number}")
    return found


def exists_from_root(path: str) -> bool:
    first, *others = path.split("|")  # config/models/glove_object|glove_pose|glove_weight
    candidates = [first] + [str(Path(first).parent / other) for other in others]
    return all(any(ROOT.glob(c)) if "*" in c else (ROOT / c).exists() for c in candidates)


def test_top_level_launch_and_config_are_the_bringup_packages_folders():
    for name in ("launch", "config"):
        link = ROOT / name
        assert link.is_symlink() and not Path(link.readlink()).is_absolute(), f"{name}: a relative link"
        assert link.resolve() == (BRINGUP / name).resolve()
    assert (ROOT / "config" / "models" / "cnn2" / "model.pt").is_file()
    assert (ROOT / "launch" / "hand.launch.py").is_file()


def test_the_documents_name_many_repository_paths():
    paths = named_paths()
    assert {"config/glove_driver.yaml", "config/models/cnn2", "config/glove/layout.yaml"} <= set(paths)
    assert len(paths) > 50


@pytest.mark.parametrize("path", sorted(named_paths()))
def test_every_repository_path_the_documents_name_exists_from_the_root(path):
    assert exists_from_root(path), f"{path} (named at {', '.join(named_paths()[path])}) is not in the repository"


def shown_commands(program: str) -> list[tuple[str, str]]:
    """(file:line, command line) of every one-line command of the documents and the node docstrings that
    runs `program`."""
    found = []
    for source in [*DOCUMENTS, *NODE_MODULES]:
        for number, line in enumerate(source.read_text().splitlines(), 1):
            text = line.strip().strip("`")
            if text.startswith(program + " ") and not text.endswith("\\"):  # not one continued on the next line
                found.append((f"{source.relative_to(ROOT)}:{number}", text))
    return found


ROS2_RUN = [(where, line) for where, line in shown_commands("ros2 run") if "--params-file config/" in line]


def evaluates_shipped_bundles_only(line: str) -> bool:
    """A prisma-eval-force line whose bundles (the arguments before the first option) are all in the
    repository and that writes no file."""
    args = shlex.split(line)[1:]
    options = [i for i, a in enumerate(args) if a.startswith("-")]
    bundles = args[:options[0]] if options else args
    return (bool(bundles) and all("/" in b and exists_from_root(b) for b in bundles)
            and not {"--plots", "--json", "--table"} & set(args))


EVAL = [(where, line) for where, line in shown_commands("prisma-eval-force") if evaluates_shipped_bundles_only(line)]


def test_the_runnable_commands_are_found():
    assert len(ROS2_RUN) >= 8 and {"stag_glove glove_driver", "stag_glove glove_perception",
                                    "prisma_force_estimator force_estimator"} <= {
        " ".join(shlex.split(line)[2:4]) for _, line in ROS2_RUN}
    assert EVAL, "docs/force_estimation.md shows prisma-eval-force on the shipped bundle"


@pytest.mark.parametrize("where, line", ROS2_RUN, ids=[w for w, _ in ROS2_RUN])
def test_ros2_run_with_a_params_file_from_config_starts_the_node(ros, where, line):
    args = shlex.split(line)
    node = args[3]  # ros2 run <package> <executable>: each node is named after its executable
    with NodeProcess(args, cwd=ROOT) as proc:
        assert proc.wait_for_output(f"[{node}]: ", 60.0), f"{where}: {line}\n{proc.output}"
        proc.wait_until_spinning(ros, f"/{node}", 60.0)
        result = proc.interrupt(30.0)
    assert result.returncode == 0, f"{where}: {line}\n{result.output}"
    assert "Traceback" not in result.output and "[FATAL]" not in result.output, result.output


@pytest.mark.parametrize("where, line", EVAL, ids=[w for w, _ in EVAL])
def test_prisma_eval_force_on_the_shipped_bundle_runs(where, line):
    args = [sys.executable, "-m", "prisma_force_estimator.cli", "eval", *shlex.split(line)[1:]]
    result = subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, f"{where}: {line}\n{result.stdout}{result.stderr}"
    assert "| cnn2 |" in result.stdout and "push_fz ok" in result.stdout, result.stdout


def launch_table() -> dict[str, str]:
    """docs/architecture.md's launch-file table: file name -> its arguments cell."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    section = text.split("### Launch files", 1)[1].split("\n\n", 1)[0]
    rows = [line.split(" | ") for line in section.splitlines() if line.startswith("| ") and ".launch.py" in line]
    return {cells[0].strip("| "): cells[2] for cells in rows}


def test_the_launch_table_names_exactly_the_arguments_each_launch_file_declares():
    table = launch_table()
    files = sorted(p.name for p in LAUNCH.glob("*.launch.py"))
    assert sorted(table) == files, "docs/architecture.md's launch table: one row per file in launch/"
    for name, cell in table.items():
        declared = set(declared_arguments(LAUNCH / name))
        named = set(re.findall(r"`([a-z_]+)`", cell))  # `x:=y`, `<dir>/servos`: examples, not names
        assert declared, f"{name} declares no argument"
        extra, missing = sorted(named - declared), sorted(declared - named)
        assert not extra and not missing, (f"docs/architecture.md, {name}'s row: not in the launch file {extra}, "
                                           f"declared but not in the row {missing}")


def launch_lines() -> list[tuple[str, str, str]]:
    """(where, launch file, the rest of the line) for each documented `ros2 launch prisma_bringup`."""
    found = []
    for source in [*DOCUMENTS, *sorted(LAUNCH.glob("*.launch.py"))]:
        for number, line in enumerate(source.read_text().splitlines(), 1):
            for match in re.finditer(r"ros2 launch prisma_bringup (\w+\.launch\.py)([^`|]*)", line):
                found.append((f"{source.relative_to(ROOT)}:{number}", match.group(1), match.group(2)))
    return found


def test_documented_launch_lines_are_found():
    files = {file for _, file, _ in launch_lines()}
    assert files == {p.name for p in LAUNCH.glob("*.launch.py")}, "every launch file has a documented line"


@pytest.mark.parametrize("where,file,rest", launch_lines())
def test_a_documented_launch_line_passes_arguments_its_file_declares(where, file, rest):
    assert (LAUNCH / file).is_file(), f"{where}: no launch file {file}"
    declared = declared_arguments(LAUNCH / file)
    for name, value in re.findall(r"(\w+):=(\S+)", rest):
        assert name in declared, f"{where}: {file} declares no argument {name} (it has {sorted(declared)})"
        choices = declared[name]
        assert choices is None or value in choices, f"{where}: {name}:={value}, but {file} takes {choices}"


def test_the_readme_is_a_front_door_not_a_manual():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f"README.md has {len(lines)} lines, at most {README_MAX_LINES}: move the detail into a docs/ page "
        "and link it from the README's table 'Where each task is documented'")


def test_the_readme_starts_each_kind_of_hand_and_sends_one_grasp():
    text = (ROOT / "README.md").read_text()
    launches = [rest for _, file, rest in launch_lines() if file == "hand.launch.py"]
    for kind in ("sim:=true", "hardware:=emulated", "sim:=false"):
        assert kind in text and any(kind in rest for rest in launches), f"README.md: no hand.launch.py line with {kind}"
    assert "ros2 action send_goal --feedback /prisma/grasp prisma_msgs/action/Grasp" in text


def test_the_readmes_links_into_the_handbook_resolve():
    text = (ROOT / "README.md").read_text()
    pages = set(re.findall(r"\]\((docs/[\w.]+\.md)(?:#[\w-]+)?\)", text))
    assert len(pages) >= 10, f"README.md links {sorted(pages)}: the table 'Where each task is documented'"
    missing = sorted(p for p in pages if not (ROOT / p).is_file())
    assert not missing, f"README.md links pages that are not in docs/: {missing}"
