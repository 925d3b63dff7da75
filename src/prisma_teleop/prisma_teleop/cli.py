"""prisma-teleop-stag-session: a STAG glove session of held hand poses for glove_driver to replay.

    prisma-teleop-stag-session /tmp/stag_poses.h5
    ros2 launch prisma_bringup teleop.launch.py input:=stag glove_backend:=replay replay_file:=/tmp/stag_poses.h5

The session (stag_session.py): empty, pinch, empty, power, empty, lateral, empty, 108 frames, 15 s
at the glove's 7.3 frames/s. Only the standard library and prisma_common's argument checks are
imported before the arguments are checked (--help stays light).
"""
from __future__ import annotations

from prisma_common.cli_args import ArgumentParser, command, non_negative_int, output_file

SUFFIXES = (".h5", ".hdf5", ".mat")


@command("prisma-teleop-stag-session")
def stag_session_main(argv: list[str] | None = None) -> int:
    parser = ArgumentParser(prog="prisma-teleop-stag-session", description=__doc__.splitlines()[0])
    parser.add_argument("out", type=output_file(*SUFFIXES), help="the dataset file to write (.h5, .hdf5 or .mat; "
                                                                 "replaced)")
    parser.add_argument("--seed", type=non_negative_int, default=0, help="the synthetic wearer's seed (default 0)")
    args = parser.parse_args(argv)
    from .stag_session import SESSION, write_session  # scipy, h5py: once the arguments are checked

    ds = write_session(args.out, args.seed)
    script = ", ".join(f"{pose} {frames}" for pose, frames in SESSION)
    print(f"wrote {args.out}: {len(ds)} frames ({script}); replay it with glove_driver's backend replay")
    return 0
