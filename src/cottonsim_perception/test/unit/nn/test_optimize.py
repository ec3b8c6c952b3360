"""The inference speed-ups keep the outputs: frozen channels-last graph and cv2 mask upsampling."""
import numpy as np
import pytest
import torch
from scipy.optimize import linear_sum_assignment

from cottonsim_perception.inference import Predictor
from cottonsim_perception.nn.letterbox import LetterboxTransform, letterbox
from cottonsim_perception.nn.models import ModelConfig, build_model
from cottonsim_perception.nn.optimize import freeze_for_inference
from cottonsim_perception.nn.postprocess import PostprocessConfig


@pytest.fixture(scope="module", params=["seg", "seg_stride1", "det"])
def weights(request, tmp_path_factory, save_small_random_network):
    return save_small_random_network(str(tmp_path_factory.mktemp("w") / f"{request.param}.pt"), request.param)


def test_frozen_network_equals_eager(weights):
    eager = Predictor(weights, threads=1, optimize=False)
    fast = Predictor(weights, threads=1, optimize=True)
    x = torch.rand(1, 3, 128, 160, generator=torch.Generator().manual_seed(2))
    a, b = eager.network(x), fast.network(x.contiguous(memory_format=torch.channels_last))
    a = a if isinstance(a, tuple) else (a,)
    b = b if isinstance(b, tuple) else (b,)
    assert len(a) == len(b)
    for u, v in zip(a, b):
        assert u.shape == v.shape
        # boxes in input px (up to ~160), probabilities, coefficients, prototypes: float rounding only
        assert torch.allclose(u, v, rtol=1e-4, atol=1e-3), float((u - v).abs().max())


def test_frozen_predictions_equal_eager(weights):
    eager = Predictor(weights, threads=1, optimize=False)
    fast = Predictor(weights, threads=1, optimize=True)
    rng = np.random.default_rng(3)
    for shape in ((480, 640, 3), (120, 200, 3)):
        img = rng.integers(0, 255, shape, dtype=np.uint8)
        # threshold in the widest gap between the 30th..60th best anchor scores (an untrained
        # network's scores crowd together, 1e-6 apart); iou_threshold 1.0 turns NMS off, else near-tied overlapping boxes would
        # let a 1e-7 score difference reorder the greedy suppression
        x = torch.from_numpy(letterbox(img, 160, 128)[0]).permute(2, 0, 1)[None].float().div(255.0)
        out = eager.network(x.contiguous())
        pred = out[0] if isinstance(out, tuple) else out
        nc = eager.config.num_classes
        best = np.sort(pred[0, :, 4:4 + nc].max(dim=1).values.numpy())[::-1]
        k = 30 + int(np.argmax(best[29:60] - best[30:61]))
        assert best[k - 1] - best[k] > 5e-6      # scores differ by < 1e-6 between the two
        post = PostprocessConfig(conf_threshold=float(best[k - 1] + best[k]) / 2, iou_threshold=1.0)
        eager.post_config = fast.post_config = post
        da, db = eager.predict(img), fast.predict(img)
        assert len(da) == len(db) == k
        # pair the detections one-to-one, nearest in box and score (an untrained network repeats boxes)
        dist = np.abs(da.boxes_xyxy[:, None] - db.boxes_xyxy[None]).max(axis=2) \
            + 100.0 * np.abs(da.scores[:, None] - db.scores[None])
        rows, match = linear_sum_assignment(dist)
        assert np.array_equal(rows, np.arange(len(da)))
        assert np.allclose(da.boxes_xyxy, db.boxes_xyxy[match], atol=1e-2)
        assert np.allclose(da.scores, db.scores[match], atol=1e-4)
        assert np.array_equal(da.classes, db.classes[match])
        if da.masks is not None:
            # a pixel may flip only where the soft mask is within rounding of the threshold
            assert (da.masks != db.masks[match]).mean() < 1e-4


def test_freeze_rejects_training_mode():
    with pytest.raises(ValueError, match="eval-mode"):
        freeze_for_inference(build_model(ModelConfig.scene_segmenter(width_multiple=0.0625)).train(), 96, 128)


def _bilinear_half_pixel(img: np.ndarray, out_h: int, out_w: int) -> np.ndarray:
    """Reference bilinear resize written out: half-pixel centres, source clamped to the edges."""
    h, w = img.shape

    def axis(n_out, n_in):
        src = np.clip((np.arange(n_out) + 0.5) * (n_in / n_out) - 0.5, 0, None)
        i0 = np.minimum(np.floor(src).astype(int), n_in - 1)
        i1 = np.minimum(i0 + 1, n_in - 1)
        return i0, i1, src - i0

    y0, y1, fy = axis(out_h, h)
    x0, x1, fx = axis(out_w, w)
    top = img[y0][:, x0] * (1 - fx) + img[y0][:, x1] * fx
    bot = img[y1][:, x0] * (1 - fx) + img[y1][:, x1] * fx
    return top * (1 - fy[:, None]) + bot * fy[:, None]


def test_masks_to_original_is_bilinear_then_threshold():
    # 640x480 into 320x256 (8 px bars top and bottom), masks on the quarter grid: crop rows 2..62
    t = LetterboxTransform.fit(640, 480, 320, 256)
    soft = torch.rand(3, 64, 80, generator=torch.Generator().manual_seed(4))
    out = t.masks_to_original(soft, threshold=0.5)
    assert out.shape == (3, 480, 640) and out.dtype == bool
    for i in range(3):
        ref = _bilinear_half_pixel(soft[i, 2:62].double().numpy(), 480, 640)
        clear = np.abs(ref - 0.5) > 1e-5
        assert np.array_equal(out[i][clear], (ref > 0.5)[clear])
        assert clear.mean() > 0.99
    assert t.masks_to_original(torch.zeros(0, 64, 80)).shape == (0, 480, 640)


def _random_windows(rng, n, height, width):
    """n random mask windows on a (height, width) grid, some None, some reaching into the letterbox bars."""
    windows = []
    for _ in range(n):
        if rng.random() < 0.1:
            windows.append(None)
            continue
        r0, r1 = sorted(rng.choice(height + 1, size=2, replace=False))
        c0, c1 = sorted(rng.choice(width + 1, size=2, replace=False))
        soft = torch.from_numpy(rng.random((r1 - r0, c1 - c0)).astype(np.float32))
        windows.append(((int(r0), int(r1), int(c0), int(c1)), soft))
    return windows


@pytest.mark.parametrize("src, dst, grid", [((640, 480), (320, 256), (80, 64)),      # stride-2 prototypes
                                            ((640, 480), (320, 256), (160, 128)),    # stride-1 (detail)
                                            ((640, 480), (640, 512), (160, 128)),
                                            ((720, 540), (320, 256), (160, 128))])   # 2.25x: dense fallback
def test_window_masks_to_original_equal_the_dense_masks(src, dst, grid):
    from cottonsim_perception.nn.letterbox import dense_masks
    t = LetterboxTransform.fit(src[0], src[1], dst[0], dst[1])
    rng = np.random.default_rng(7)
    w, h = grid
    for _ in range(4):
        windows = _random_windows(rng, 12, h, w)
        # a window entirely inside the top bar maps to nothing
        windows.append(((0, 1, 3, 9), torch.ones(1, 6)))
        got = t.window_masks_to_original(windows, h, w, threshold=0.5)
        want = t.masks_to_original(dense_masks(windows, h, w), threshold=0.5)
        assert got.shape == want.shape == (len(windows), src[1], src[0])
        assert np.array_equal(got, want)
        assert got.any() and not got[-1].any()
    assert t.window_masks_to_original([], h, w).shape == (0, src[1], src[0])
