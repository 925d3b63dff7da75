"""prisma-policy's command line: a small training run end to end, and bad input as one line and exit 2
with nothing written."""
from __future__ import annotations

import pytest

from prisma_dataset.bag_export import WRENCH
from prisma_policy.cli import main


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("prisma-policy") and ": error: " in err[0]
    return err[0]


def test_train_writes_the_model_and_says_the_loss(tmp_path, capsys, tiny_dataset):
    root = tiny_dataset(tmp_path / "ds")
    out = tmp_path / "models" / "policy.pt"
    assert main(["train", str(root), "--out", str(out), "--steps", "200", "--hidden", "16"]) == 0
    printed = capsys.readouterr().out
    assert "3 episodes, " in printed and "81 inputs -> 3 motor targets" in printed
    assert "step 200/200" in printed and out.is_file()
    assert [p.name for p in out.parent.iterdir()] == ["policy.pt"]


def test_a_missing_feature_is_one_line(tmp_path, capsys, tiny_dataset):
    root = tiny_dataset(tmp_path / "ds", drop=WRENCH)
    out = tmp_path / "policy.pt"
    assert main(["train", str(root), "--out", str(out), "--steps", "10"]) == 2
    assert "has no feature observation.wrench" in one_error_line(capsys)
    assert not out.exists()


def test_a_directory_that_is_not_a_dataset_is_one_line(tmp_path, capsys, tiny_dataset):
    (tmp_path / "not_a_dataset").mkdir()
    assert main(["train", str(tmp_path / "not_a_dataset"), "--out", str(tmp_path / "p.pt")]) == 2
    assert "is not a LeRobot dataset (no meta/info.json)" in one_error_line(capsys)
    with pytest.raises(SystemExit) as exit_:
        main(["train", str(tmp_path / "missing"), "--out", str(tmp_path / "p.pt")])
    assert exit_.value.code == 2
    assert "missing" in one_error_line(capsys)


def test_an_unwritable_out_is_one_line(tmp_path, capsys, tiny_dataset):
    root = tiny_dataset(tmp_path / "ds")
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for out in (blocker / "policy.pt", tmp_path / "policy.txt"):
        with pytest.raises(SystemExit) as exit_:
            main(["train", str(root), "--out", str(out), "--steps", "10"])
        assert exit_.value.code == 2
        assert str(out) in one_error_line(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "ds"]


def test_eval_refuses_a_file_that_is_not_a_model(tmp_path, capsys, tiny_dataset):
    path = tmp_path / "model.pt"
    path.write_bytes(b"\x00\x01 not a torch file")
    assert main(["eval", str(path), "--trials", "1", "--plot", str(tmp_path / "e.png")]) == 2
    assert "is not a prisma-policy model" in one_error_line(capsys)
    assert not (tmp_path / "e.png").exists()
