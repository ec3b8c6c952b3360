"""ConsumerWait: the simulation waits at the end of a frame's slot until its consumer is done; not for a dead one."""
import pytest

from cottonsim_world.consumer_wait import ConsumerWait


def test_a_frame_blocks_from_the_end_of_its_slot_until_it_is_done():
    wait = ConsumerWait({"front": 0.2})
    wait.sent("front", 1.0)
    assert wait.blocking(1.1) is None              # inside its slot: the consumer still has time
    assert wait.blocking(1.2) == ("front", 1.0)    # the slot is over
    wait.done("front", 1.0 + 1e-9)                 # the stamp after a trip through ROS nanoseconds
    assert wait.blocking(5.0) is None


def test_done_answers_every_frame_up_to_its_stamp_and_the_oldest_blocks_first():
    wait = ConsumerWait({"left": 0.5, "front": 0.2})
    for t in (0.0, 0.5, 1.0):
        wait.sent("left", t)
    wait.sent("front", 0.2)
    assert wait.blocking(2.0) == ("left", 0.0)
    wait.done("left", 0.5)
    assert wait.blocking(2.0) == ("front", 0.2)
    wait.done("front", 0.2)
    assert wait.blocking(2.0) == ("left", 1.0)


def test_a_consumer_that_does_not_answer_is_not_waited_for_until_it_answers_again():
    wait = ConsumerWait({"left": 0.5})
    wait.sent("left", 0.0)
    wait.timed_out("left")
    assert wait.blocking(10.0) is None and not wait.answering("left") and wait.timeouts["left"] == 1
    wait.sent("left", 0.5)                         # not waited for
    assert wait.blocking(10.0) is None
    wait.done("left", 0.5)                         # it is back
    wait.sent("left", 1.0)
    assert wait.blocking(1.5) == ("left", 1.0)


def test_cameras_not_waited_for_are_ignored_and_bad_slots_refused():
    wait = ConsumerWait({"left": 0.5})
    wait.sent("front", 0.0)
    wait.done("front", 0.0)
    assert wait.blocking(10.0) is None
    with pytest.raises(ValueError, match="slot of camera 'left'"):
        ConsumerWait({"left": 0.0})


def test_next_slot_end_is_the_earliest_one_not_answered():
    wait = ConsumerWait({"left": 0.5, "front": 0.2})
    assert wait.next_slot_end_s() == float("inf")
    wait.sent("left", 1.0)
    wait.sent("front", 1.2)
    assert wait.next_slot_end_s() == pytest.approx(1.4)
    wait.done("front", 1.2)
    assert wait.next_slot_end_s() == pytest.approx(1.5)
