"""cli_args: an output that cannot be created is refused while the arguments are parsed, and leaves
nothing; one that fails later (atomic_output's OutputError) is one line and exit 2 all the same."""
from __future__ import annotations

import argparse

import pytest

from prisma_common.atomic import OutputError, atomic_output
from prisma_common.cli_args import (
    ArgumentParser,
    check_bundle_out,
    command,
    existing_dir,
    existing_file,
    existing_path,
    output_dir,
    output_file,
    ros_namespace,
)


def test_a_creatable_output_passes_and_the_check_leaves_nothing(tmp_path):
    nested = tmp_path / "a" / "b" / "cal.npz"
    assert output_file(".npz")(str(nested)) == nested
    assert output_dir(str(tmp_path / "plots" / "more")) == tmp_path / "plots" / "more"
    (tmp_path / "existing").mkdir()
    assert output_dir(str(tmp_path / "existing")) == tmp_path / "existing"
    check_bundle_out(tmp_path / "bundle")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["existing"] and not any((tmp_path / "existing").iterdir())


@pytest.mark.parametrize("check", [output_file(".png"), output_dir], ids=["file", "directory"])
def test_an_output_under_proc_or_with_a_too_long_name_is_refused_naming_path_and_reason(tmp_path, check):
    with pytest.raises(argparse.ArgumentTypeError, match=r"/proc/prisma-no-such-dir.*choose another"):
        check("/proc/prisma-no-such-dir/out.png")
    long = str(tmp_path / ("x" * 300 + ".png"))
    with pytest.raises(argparse.ArgumentTypeError, match="File name too long"):
        check(long)
    assert list(tmp_path.iterdir()) == []


def test_output_error_during_the_run_is_one_line_and_exit_2(tmp_path, capsys):
    @command("prisma-demo")
    def main(argv=None) -> int:
        ArgumentParser(prog="prisma-demo").parse_args(argv or [])
        print("working")
        with atomic_output(tmp_path / ("x" * 300)) as staged:
            staged.write_text("never")
        return 0

    assert main([]) == 2
    out, err = capsys.readouterr()
    assert out == "working\n" and err.count("\n") == 1
    assert err.startswith("prisma-demo: error: cannot create ") and "(File name too long)" in err
    assert list(tmp_path.iterdir()) == []
    assert issubclass(OutputError, OSError)


def test_an_input_path_must_exist_and_be_of_its_kind(tmp_path):
    notes, folder, missing = tmp_path / "notes.txt", tmp_path / "runs", tmp_path / "nowhere"
    notes.write_text("x")
    folder.mkdir()
    assert (existing_file(str(notes)), existing_dir(str(folder))) == (notes, folder)
    assert (existing_path(str(notes)), existing_path(str(folder))) == (notes, folder)
    refusals = [(existing_file, missing, "nowhere: no such file; check the path"),
                (existing_file, folder, "runs is a directory; give a file"),
                (existing_dir, missing, "nowhere: no such directory; check the path"),
                (existing_dir, notes, "notes.txt is a file; give a directory"),
                (existing_path, missing, "nowhere: no such file or directory; check the path"),
                (existing_path, "", "an empty path; give a file or directory name")]
    for check, path, message in refusals:
        with pytest.raises(argparse.ArgumentTypeError) as err:
            check(str(path))
        assert str(err.value).endswith(message), (check.__name__, str(err.value))


def test_a_namespace_is_given_with_or_without_slashes_and_checked():
    assert [ros_namespace(text) for text in ("left", "/left/", "/", "", "hands/left_2")] == [
        "left", "left", "", "", "hands/left_2"]
    for bad in ("9 bad", "left/2nd", "le-ft"):
        with pytest.raises(argparse.ArgumentTypeError, match=f"'{bad}' is not a ROS namespace"):
            ros_namespace(bad)
