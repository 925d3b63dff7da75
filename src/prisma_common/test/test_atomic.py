"""atomic_output: an output appears whole at its path or not at all, whatever stops the writer."""
from __future__ import annotations

import os

import pytest

from prisma_common.atomic import OutputError, atomic_output, staging_dir


def leftovers(directory):
    return sorted(p.name for p in directory.iterdir() if ".partial-" in p.name)


def test_file_is_staged_under_its_own_name_and_renamed_into_place(tmp_path):
    target = tmp_path / "plots" / "pad.png"
    with atomic_output(target) as staged:
        assert staged.name == "pad.png"  # savefig picks the format from this name
        assert staged.parent == tmp_path / "plots" / f"pad.png.partial-{os.getpid()}"
        assert staged.parent == staging_dir(target)
        staged.write_bytes(b"complete")
        assert not target.exists()  # nothing at the target until the block ends
    assert target.read_bytes() == b"complete"
    assert leftovers(target.parent) == []


@pytest.mark.parametrize("stop", [RuntimeError("disk full"), KeyboardInterrupt()], ids=["error", "ctrl-c"])
def test_an_interrupted_write_leaves_nothing_and_keeps_the_old_file(tmp_path, stop):
    new = tmp_path / "new.json"
    old = tmp_path / "old.json"
    old.write_text("the earlier run")
    for target in (new, old):
        with pytest.raises(type(stop)):
            with atomic_output(target) as staged:
                staged.write_text("half of it")
                raise stop
    assert not new.exists()
    assert old.read_text() == "the earlier run"
    assert leftovers(tmp_path) == []
    # a rerun is not refused by anything the interrupted one left
    with atomic_output(new) as staged:
        staged.write_text("whole")
    assert new.read_text() == "whole"


@pytest.mark.parametrize("stop", [ValueError("bad sample"), KeyboardInterrupt()], ids=["error", "ctrl-c"])
def test_an_interrupted_directory_leaves_nothing_and_keeps_the_old_one(tmp_path, stop):
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("old")
    with pytest.raises(type(stop)):
        with atomic_output(bag) as staged:
            staged.mkdir()
            (staged / "metadata.yaml").write_text("new, unfinished")
            raise stop
    assert (bag / "metadata.yaml").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


def test_a_finished_directory_replaces_the_old_one_whole(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "stale.png").write_text("from an earlier run")
    (out / "summary.md").write_text("old")
    with atomic_output(out) as staged:
        staged.mkdir()
        (staged / "summary.md").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["summary.md"]
    assert (out / "summary.md").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_replace_false_refuses_an_existing_target_before_writing(tmp_path):
    target = tmp_path / "out_bag"
    target.mkdir()
    with pytest.raises(FileExistsError, match="out_bag already exists"):
        with atomic_output(target, replace=False):
            pytest.fail("the block must not run")
    assert list(target.iterdir()) == [] and leftovers(tmp_path) == []


def test_kind_mismatch_and_empty_output_are_refused_without_loss(tmp_path):
    directory = tmp_path / "plots"
    directory.mkdir()
    (directory / "keep.png").write_text("x")
    with pytest.raises(IsADirectoryError, match="plots is a directory"):
        with atomic_output(directory) as staged:
            staged.write_text("a file where a directory is")
    assert (directory / "keep.png").read_text() == "x"
    afile = tmp_path / "notes.txt"
    afile.write_text("mine")
    with pytest.raises(NotADirectoryError, match="notes.txt is a file"):
        with atomic_output(afile) as staged:
            staged.mkdir()
    assert afile.read_text() == "mine"
    with pytest.raises(FileNotFoundError, match="nothing was written"):
        with atomic_output(tmp_path / "never.txt"):
            pass
    assert not (tmp_path / "never.txt").exists()
    assert leftovers(tmp_path) == []


def test_a_leftover_of_a_killed_run_with_the_same_pid_is_cleared(tmp_path):
    target = tmp_path / "cal.npz"
    stale = staging_dir(target)
    stale.mkdir()
    (stale / "cal.npz").write_bytes(b"killed half way")
    with atomic_output(target) as staged:
        assert not staged.exists()
        staged.write_bytes(b"whole")
    assert target.read_bytes() == b"whole" and not stale.exists()


@pytest.mark.parametrize("where, named, reason", [
    ("/proc/prisma-no-such-dir/out.png", "/proc/prisma-no-such-dir", "No such file or directory"),
    ("{tmp}/" + "x" * 300 + ".png", "x" * 300, "File name too long"),
], ids=["no-directory-in-proc", "name-too-long"])
def test_an_output_that_cannot_be_created_raises_output_error_naming_it(tmp_path, where, named, reason):
    """/proc takes no new directory (not even root's) and no file system takes a 300-byte name:
    OutputError, an OSError, names the path and the reason; nothing is left behind."""
    with pytest.raises(OutputError) as info:
        with atomic_output(where.replace("{tmp}", str(tmp_path))) as staged:
            staged.write_bytes(b"never")
    assert isinstance(info.value, OSError)
    message = str(info.value)
    assert message.startswith("cannot create ") and named in message and f"({reason})" in message
    assert list(tmp_path.iterdir()) == []
