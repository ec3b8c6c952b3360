"""Fusion of boll detections over frames into targets."""
import numpy as np
import pytest

from cottonsim_manipulation.harvest.targets import (
    ABANDONED,
    CONFIRMED,
    PICKED,
    TENTATIVE,
    BollDetection3D,
    TargetFusion,
    TargetFusionConfig,
)

SIGMA = 0.005


def seen(rng, truth, sigma=SIGMA):
    return BollDetection3D(truth + rng.normal(0.0, sigma, 3), sigma)


def test_the_same_boll_over_many_frames_is_one_target():
    rng = np.random.default_rng(0)
    truth = np.array([3.0, 12.0, 0.6])
    fusion = TargetFusion()
    for k in range(60):
        ids = fusion.update([seen(rng, truth)], stamp_s=0.1 * k)
        assert ids == [0]
    (target,) = fusion.targets()
    assert target.observations == 60 and target.state == CONFIRMED
    # The running mean beats a single detection (sigma 5 mm per axis).
    assert np.linalg.norm(target.position_m - truth) < 0.003
    assert target.sigma_m == pytest.approx(SIGMA / np.sqrt(60))
    assert target.first_seen_s == 0.0 and target.last_seen_s == pytest.approx(5.9)


@pytest.mark.parametrize("seed", range(5))
def test_two_bolls_four_centimetres_apart_stay_two(seed):
    rng = np.random.default_rng(seed)
    a, b = np.array([3.0, 12.0, 0.6]), np.array([3.0, 12.04, 0.6])
    fusion = TargetFusion()
    for k in range(80):
        frame = []
        if k % 5 != 1:
            frame.append(seen(rng, a))
        if k % 7 != 3 and k > 3:                # b comes into view after a
            frame.append(seen(rng, b))
        rng.shuffle(frame)
        fusion.update(frame, stamp_s=0.1 * k)
    targets = fusion.targets()
    assert len(targets) == 2
    positions = sorted((t.position_m for t in targets), key=lambda p: p[1])
    assert np.linalg.norm(positions[0] - a) < 0.004 and np.linalg.norm(positions[1] - b) < 0.004


def test_targets_persist_out_of_view_and_a_picked_boll_never_returns():
    rng = np.random.default_rng(2)
    a, b = np.array([3.0, 12.0, 0.6]), np.array([3.0, 12.5, 0.4])
    fusion = TargetFusion(TargetFusionConfig(reopen_observations=0))
    for k in range(5):
        fusion.update([seen(rng, a), seen(rng, b)], stamp_s=k)
    for k in range(5, 50):                       # b leaves the view
        fusion.update([seen(rng, a)], stamp_s=k)
    assert len(fusion.open_targets()) == 2
    (ta,) = [t for t in fusion.targets() if np.linalg.norm(t.position_m - a) < 0.01]
    fusion.mark_picked(ta.target_id)
    assert fusion.target(ta.target_id).state == PICKED
    # Detections at the picked boll's place (e.g. a leftover, or a stale frame) are ignored.
    for k in range(50, 60):
        assert fusion.update([seen(rng, a)], stamp_s=k) == [-1]
    assert len(fusion) == 2 and len(fusion.open_targets()) == 1
    # A new boll 10 cm away is a new target.
    ids = fusion.update([BollDetection3D(a + [0, 0, 0.1], SIGMA)], stamp_s=61)
    assert ids == [2] and fusion.target(2).state == TENTATIVE


def test_confirmation_failures_and_abandon():
    fusion = TargetFusion(TargetFusionConfig(confirm_observations=3, max_attempts=2))
    p = np.array([1.0, 2.0, 0.5])
    fusion.update([BollDetection3D(p, SIGMA)], 0.0)
    fusion.update([BollDetection3D(p, SIGMA)], 0.1)
    assert fusion.target(0).state == TENTATIVE and not fusion.open_targets()
    fusion.update([BollDetection3D(p, SIGMA)], 0.2)
    assert fusion.target(0).state == CONFIRMED
    assert fusion.mark_failed(0) == CONFIRMED
    assert fusion.mark_failed(0) == ABANDONED
    # An abandoned target still absorbs its detections (no duplicate), but is not open.
    assert fusion.update([BollDetection3D(p, SIGMA)], 0.3) == [0]
    assert len(fusion) == 1 and not fusion.open_targets()
    fusion.mark_picked(0)
    with pytest.raises(ValueError, match="already picked"):
        fusion.mark_failed(0)
    with pytest.raises(KeyError, match="no boll target 7"):
        fusion.mark_picked(7)


def test_gate_limits():
    p = np.array([0.0, 0.0, 0.0])
    # Large sigmas: the gate is capped at max_gate_m (5 cm).
    fusion = TargetFusion()
    fusion.update([BollDetection3D(p, 0.05)], 0.0)
    assert fusion.update([BollDetection3D(p + [0.049, 0, 0], 0.05)], 0.1) == [0]
    assert fusion.update([BollDetection3D(p + [0.08, 0, 0], 0.05)], 0.2) == [1]
    # Small sigmas: 5 * sqrt(2) * 2 mm = 14 mm, raised to min_gate_m (2.5 cm).
    tight = TargetFusion()
    tight.update([BollDetection3D(p, 0.002)], 0.0)
    assert tight.update([BollDetection3D(p + [0.024, 0, 0], 0.002)], 0.1) == [0]
    assert tight.update([BollDetection3D(p + [0.04, 0, 0], 0.002)], 0.2) == [1]
    # In between the statistical gate rules: 5 * sqrt(2) * 6 mm = 42 mm.
    mid = TargetFusion()
    mid.update([BollDetection3D(p, 0.006)], 0.0)
    assert mid.update([BollDetection3D(p + [0.041, 0, 0], 0.006)], 0.1) == [0]
    mid2 = TargetFusion()
    mid2.update([BollDetection3D(p, 0.006)], 0.0)
    assert mid2.update([BollDetection3D(p + [0.043, 0, 0], 0.006)], 0.1) == [1]


def test_two_bolls_in_one_frame_never_merge():
    fusion = TargetFusion()
    p = np.array([0.0, 0.0, 0.0])
    ids = fusion.update([BollDetection3D(p, 0.01), BollDetection3D(p + [0.01, 0, 0], 0.01)], 0.0)
    assert sorted(ids) == [0, 1]
    # Both near the existing targets, and a third one near both: one detection per target.
    ids = fusion.update([BollDetection3D(p + [0.002, 0, 0], 0.01), BollDetection3D(p + [0.008, 0, 0], 0.01),
                         BollDetection3D(p + [0.005, 0, 0], 0.01)], 0.1)
    assert ids[:2] == [0, 1] and ids[2] == 2
    assert [t.observations for t in fusion.targets()] == [2, 2, 1]


def test_a_picked_target_still_seen_after_its_pick_is_open_again():
    """The nozzle took a neighbour on its way in: the target's own boll still hangs there and is seen again."""
    rng = np.random.default_rng(3)
    a = np.array([3.0, 12.0, 0.6])
    fusion = TargetFusion()
    for k in range(5):
        fusion.update([seen(rng, a)], stamp_s=0.1 * k)
    (target,) = fusion.targets()
    fusion.mark_picked(target.target_id, stamp_s=0.5)
    # the second after the pick (the carried boll, a frame from before) does not count
    for k in range(6):
        assert fusion.update([seen(rng, a)], stamp_s=0.6 + 0.1 * k) == [-1]
    assert fusion.target(target.target_id).state == PICKED
    moved = a + [0.0, 0.01, 0.0]                     # seen again, 1 cm from the old estimate
    assert fusion.update([BollDetection3D(moved, SIGMA)], stamp_s=1.6) == [-1]
    assert fusion.update([BollDetection3D(moved, SIGMA)], stamp_s=1.6) == [-1]     # the same frame counts once
    assert fusion.update([BollDetection3D(moved, SIGMA)], stamp_s=1.7) == [-1]
    assert fusion.update([BollDetection3D(moved, SIGMA)], stamp_s=1.8) == [target.target_id]
    reopened = fusion.target(target.target_id)
    assert reopened.state == CONFIRMED and fusion.open_targets() == [reopened]
    np.testing.assert_allclose(reopened.position_m, moved, atol=1e-9)
    assert reopened.last_seen_s == 1.8 and len(fusion) == 1
    # picked again, and this time gone: nothing comes back
    fusion.mark_picked(target.target_id, stamp_s=2.0)
    for k in range(10):
        fusion.update([], stamp_s=3.0 + k)
    assert fusion.target(target.target_id).state == PICKED


def test_bad_input():
    with pytest.raises(ValueError, match="position"):
        BollDetection3D(np.array([0, np.nan, 0]), 0.01)
    with pytest.raises(ValueError, match="sigma_m"):
        BollDetection3D(np.zeros(3), 0.0)
    with pytest.raises(ValueError, match="stamp_s"):
        TargetFusion().update([], float("nan"))
    with pytest.raises(ValueError, match="BollDetection3D"):
        TargetFusion().update([np.zeros(3)], 0.0)
    with pytest.raises(ValueError, match="gate_sigma"):
        TargetFusionConfig(gate_sigma=0.0)
    with pytest.raises(ValueError, match="min_gate_m"):
        TargetFusionConfig(min_gate_m=0.06)
    with pytest.raises(ValueError, match="confirm_observations"):
        TargetFusionConfig(confirm_observations=0)
    with pytest.raises(ValueError, match="track_observations"):
        TargetFusionConfig(track_observations=-1)
    with pytest.raises(ValueError, match="reopen_observations"):
        TargetFusionConfig(reopen_observations=-1)
    with pytest.raises(ValueError, match="reopen_after_s"):
        TargetFusionConfig(reopen_after_s=float("nan"))


def test_a_tracking_target_follows_a_drifting_boll_and_a_plain_one_lags():
    """The boll moves 1 mm per frame in the fixed frame (odometry drift): 60 frames, 6 cm in all."""
    start = np.array([3.0, 12.0, 0.6])
    plain, tracking = TargetFusion(), TargetFusion(TargetFusionConfig(track_observations=5))
    for k in range(60):
        now = start + np.array([0.001 * k, 0.0, 0.0])
        plain.update([BollDetection3D(now, SIGMA)], 0.1 * k)
        tracking.update([BollDetection3D(now, SIGMA)], 0.1 * k)
    assert len(tracking) == 1
    (target,) = tracking.targets()
    assert np.linalg.norm(target.position_m - now) < 0.005
    assert target.sigma_m == pytest.approx(SIGMA / np.sqrt(5))
    # without tracking the mean stays behind; the boll outruns its gate and becomes a second target
    assert len(plain) == 2
