"""InputHealth: counts, stale and back again, black and no-estimate runs warned once per run."""
import numpy as np
import pytest

from cottonsim_perception.monitoring.input_health import HealthConfig, InputHealth, is_black


def _kinds(events):
    return [e.kind for e in events]


def test_counts_follow_what_happened_to_the_frames():
    h = InputHealth("cam")
    for t in (0.0, 0.1, 0.2):
        h.received(t)
    h.processed()
    h.processed(has_estimate=False)
    h.black()
    assert (h.frames_received, h.frames_processed, h.frames_no_estimate, h.frames_black, h.frames_stale) == \
        (3, 2, 1, 1, 0)


def test_a_camera_that_stops_goes_stale_and_is_used_again_when_it_comes_back():
    h = InputHealth("cam", HealthConfig(stale_after_s=1.0))
    h.received(0.0)
    assert h.tick(0.5) == [] and not h.stale
    events = h.tick(1.5)
    assert _kinds(events) == ["stale"] and h.stale and "1.5 s" in events[0].message
    for t in (2.0, 3.0, 5.0):                    # a 5 s blackout: every slot counted, one warning only
        assert h.tick(t) == []
    assert h.frames_stale == 4
    assert h.age_s(5.0) == pytest.approx(5.0)
    h.received(5.2)
    assert not h.stale
    events = h.tick(5.4)
    assert _kinds(events) == ["back"] and "5.2 s" in events[0].message
    assert h.frames_stale == 4 and h.frames_received == 2


def test_an_input_that_never_sends_goes_stale_from_the_first_slot():
    h = InputHealth("cam", HealthConfig(stale_after_s=1.0))
    assert h.tick(10.0) == []
    events = h.tick(11.5)
    assert _kinds(events) == ["stale"] and "no frame yet" in events[0].message
    assert h.age_s(11.5) == -1.0


def test_a_run_of_black_frames_is_warned_once_and_a_good_frame_ends_it():
    h = InputHealth("cam", HealthConfig(black_warn_frames=3))
    for _ in range(5):
        h.black()
    assert _kinds(h.tick(0.0)) == ["black"]
    h.processed()
    for _ in range(3):
        h.black()
    assert _kinds(h.tick(0.1)) == ["black"]
    assert h.frames_black == 8


def test_a_run_without_estimates_is_warned_once():
    h = InputHealth("labels", HealthConfig(no_estimate_warn_frames=4))
    for _ in range(10):
        h.processed(has_estimate=False)
    events = h.tick(0.0)
    assert _kinds(events) == ["no_estimate"] and "4 frames" in events[0].message
    h.processed(has_estimate=True)
    for _ in range(3):
        h.processed(has_estimate=False)
    assert h.tick(0.1) == []
    assert h.frames_no_estimate == 13


def test_black_frames_are_told_from_dark_ones():
    assert is_black(np.zeros((480, 640, 3), np.uint8), 2.0)
    assert is_black(np.full((48, 64, 3), 2, np.uint8), 2.0)
    assert not is_black(np.full((48, 64, 3), 20, np.uint8), 2.0)      # a dark scene is not a blackout
    with pytest.raises(ValueError, match="empty"):
        is_black(np.zeros((0, 0, 3), np.uint8), 2.0)


@pytest.mark.parametrize("key,value", [("stale_after_s", 0.0), ("stale_after_s", float("nan")),
                                       ("black_max_mean", -1.0), ("black_max_mean", 255.0),
                                       ("black_warn_frames", 0), ("no_estimate_warn_frames", 2.5)])
def test_bad_config_values_name_their_key(key, value):
    with pytest.raises(ValueError, match=key):
        HealthConfig(**{key: value})


def test_config_from_a_mapping_keeps_only_its_fields():
    cfg = HealthConfig.from_mapping({"stale_after_s": 2.0, "camera": "x"})
    assert cfg.stale_after_s == 2.0 and cfg.black_max_mean == HealthConfig().black_max_mean
