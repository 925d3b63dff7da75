"""hand_input.HandInput: per-finger samples until the per-hand stream speaks, each sample once."""
from prisma_common.hand_input import HandInput


def test_per_finger_samples_are_taken_until_the_first_per_hand_message():
    state = HandInput()
    assert state.take_finger("thumb", 10) and state.take_finger("index", 10)
    assert not state.switched
    assert state.take_hand("middle", 20)  # never came per finger: taken
    assert state.switched
    assert not state.take_finger("thumb", 30)  # after the switch the per-finger form is ignored


def test_samples_the_per_finger_stream_already_delivered_are_skipped_once():
    state = HandInput()
    for stamp in (10, 20, 30):
        assert state.take_finger("thumb", stamp)
    # the first per-hand messages still carry the scans at 20 and 30 ms: already delivered
    assert [state.take_hand("thumb", s) for s in (20, 30, 40, 50)] == [False, False, True, True]
    # past the overlap every stamp counts again, also one that goes back (a bag replayed with --loop)
    assert state.take_hand("thumb", 5)


def test_each_finger_leaves_the_overlap_on_its_own():
    state = HandInput()
    state.take_finger("thumb", 30)
    state.take_finger("index", 20)
    assert [state.take_hand(f, 30) for f in ("thumb", "index")] == [False, True]
    assert [state.take_hand(f, 40) for f in ("thumb", "index")] == [True, True]
