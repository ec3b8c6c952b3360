"""RGB-D camera (Intel RealSense D435-like): numba rasteriser or pybullet.

Why: the perception stack (segmentation, boll detection, row centring) and
the depth point clouds need images of the farm from the robot's three
RealSense cameras. ``CameraModel`` renders the plants, paints the ground and
sky analytically (``SensorScene.ground_and_sky``) and returns numpy data;
the ROS bridge turns it into Image / CameraInfo / PointCloud2.

Renderers (``CameraConfig.renderer``):

* 'numba' (default): ``sensors.fast.raster``, a compiled z-buffer
  rasteriser over the farm's triangles, a few ms per frame; agrees with
  'tiny' on semantics and depth (``test_fast_sensors.py``), colours are flat
  Lambert shading close to TinyRenderer's;
* 'tiny': pybullet's TinyRenderer in the camera's own culled render client
  (``scene.RenderClient``), the reference, 100-900 ms per 640x480 frame;
* 'egl': pybullet's EGL plugin (falls back to 'tiny' with a warning).

Frames: the pose passed to ``render`` is ``world_T_optical``: the optical
frame of REP-103 (z forward, x right, y down). Intrinsics: square pixels,
fx = fy = (W / 2) / tan(h_fov / 2), principal point at the image centre
cx = (W - 1) / 2, cy = (H - 1) / 2 in pixel-index coordinates (pixel (0, 0)
is centred at (0, 0)). Both renderers honour it: the numba rasteriser
samples pixel (col, row) at exactly u = col, v = row; TinyRenderer's own
sampling is half a pixel off, which an off-centre projection matrix
corrects (see ``CameraModel.__init__``). (Gazebo's plugin writes
(W + 1) / 2, half a pixel to a pixel off.)
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np
import pybullet as pb

from cottonsim_common.validation import require_fields, require_instance
from cottonsim_world.farm.model import SemanticClass
from cottonsim_world.sensors.fast.image_compose import compose_image, fill_cloud_xyzrgb, tile_texture
from cottonsim_world.sensors.fast.raster import draw_plants
from cottonsim_world.sensors.scene import BollVisibility, SensorScene, check_pose

_RENDERERS = ("numba", "tiny", "egl")


@dataclass(frozen=True)
class CameraConfig:
    """One RGB-D camera. Defaults: the original's RealSense Gazebo plugin.

    width/height [px]; horizontal_fov_rad (the plugin's 1.5184 rad = 87 deg;
    the paper's colour FOV is 69 deg = 1.2043 rad); near_m/far_m: clip
    planes [m]; rate_hz: publishing rate (used by the bridge); cloud_min_m /
    cloud_max_m: depth range kept in the point cloud [m]; cloud_stride: keep
    every n-th pixel in u and v for the cloud (decimation); depth_noise_std_m
    and rgb_noise_std (in 0-255 units): Gaussian noise (0 = none);
    renderer: 'numba' (compiled rasteriser, the fast default), 'tiny'
    (pybullet TinyRenderer, CPU, the reference) or 'egl' (pybullet's EGL
    plugin; falls back to 'tiny' with a warning if it cannot load);
    cull_distance_m: plants whose bounding sphere is farther than this along
    the optical axis are not rendered (inf = only frustum culling);
    plant_id_image: also return a per-pixel plant id image; seed: noise.
    lod_max_error_px ('numba' only): each plant is drawn with the coarsest
    level of detail of ``fast.instanced_plants.InstancedPlants`` whose outline error
    bound, seen at the depth of the plant's nearest bounding-sphere point, is
    at most this many pixels [px]: the middle levels (leaves with fewer
    outline points, bolls and tubes as proxies where close enough; surface
    within 1 cm / 2.5 cm of the full model) or the far level
    (``fast.level_of_detail.proxy_model_arrays``: each leaf, boll and stem part
    replaced by a few triangles of the same area, ~4.5x fewer triangles);
    0 = always full detail.
    render_rate_hz: frames rendered per second at most [Hz]; 0 (default) =
    every frame. The frames stay on the rate_hz grid (their stamps), and of
    them only the first of each slot [k, k + 1) / render_rate_hz of sim time
    is rendered and published (``cottonsim_common.rate_slots``): the frames a
    consumer that takes one frame per slot at this rate takes from every frame.
    consumer_wait_s (with render_rate_hz > 0): the ROS bridge does not step
    past the end of a frame's slot until the frame's consumer has published
    that it is done with it on /sim/frames_done, waiting at most this long
    [s, wall time] (``cottonsim_world.consumer_wait``); 0 (default) = never waits.
    """

    width: int = 640
    height: int = 480
    horizontal_fov_rad: float = 1.5184
    near_m: float = 0.01
    far_m: float = 50.0
    rate_hz: float = 30.0
    cloud_min_m: float = 0.105
    cloud_max_m: float = 8.0
    cloud_stride: int = 1
    depth_noise_std_m: float = 0.0
    rgb_noise_std: float = 0.0
    renderer: str = "numba"
    cull_distance_m: float = 25.0
    plant_id_image: bool = False
    seed: int = 0
    lod_max_error_px: float = 4.0
    render_rate_hz: float = 0.0
    consumer_wait_s: float = 0.0

    def __post_init__(self) -> None:
        require_fields(self, counts=("width", "height", "cloud_stride"),
                       non_negative=("depth_noise_std_m", "rgb_noise_std"))
        if self.width > 4096 or self.height > 4096:
            raise ValueError(f"width/height must be <= 4096 px, got {self.width}x{self.height}")
        if not (0.0 < self.horizontal_fov_rad < math.pi):
            raise ValueError(f"horizontal_fov_rad must be in (0, pi), got {self.horizontal_fov_rad}")
        if not (0.0 < self.near_m < self.far_m) or not math.isfinite(self.far_m):
            raise ValueError(f"near_m/far_m must satisfy 0 < near_m < far_m < inf, got {self.near_m}, {self.far_m}")
        if not (self.rate_hz > 0.0 and math.isfinite(self.rate_hz)):
            raise ValueError(f"rate_hz must be > 0, got {self.rate_hz}")
        if not (0.0 <= self.cloud_min_m < self.cloud_max_m):
            raise ValueError(f"cloud_min_m/cloud_max_m must satisfy 0 <= min < max, got "
                             f"{self.cloud_min_m}, {self.cloud_max_m}")
        if self.renderer not in _RENDERERS:
            raise ValueError(f"renderer must be one of {_RENDERERS}, got {self.renderer!r}")
        if not (self.lod_max_error_px >= 0.0 and math.isfinite(self.lod_max_error_px)):
            raise ValueError(f"lod_max_error_px must be a finite number >= 0, got {self.lod_max_error_px}")
        if (isinstance(self.render_rate_hz, bool) or not isinstance(self.render_rate_hz, (int, float))
                or not (math.isfinite(self.render_rate_hz) and 0.0 <= self.render_rate_hz <= self.rate_hz)):
            raise ValueError(f"render_rate_hz must be 0 (every frame) or in (0, rate_hz = {self.rate_hz}], "
                             f"got {self.render_rate_hz}")
        if (isinstance(self.consumer_wait_s, bool) or not isinstance(self.consumer_wait_s, (int, float))
                or not (math.isfinite(self.consumer_wait_s) and self.consumer_wait_s >= 0.0)):
            raise ValueError(f"consumer_wait_s must be a finite number >= 0 [s], got {self.consumer_wait_s!r}")
        if self.consumer_wait_s > 0.0 and self.render_rate_hz <= 0.0:
            raise ValueError("consumer_wait_s > 0 needs render_rate_hz > 0 (the consumer's slots), got "
                             f"render_rate_hz {self.render_rate_hz}")
        if not (self.cull_distance_m > 0.0):
            raise ValueError(f"cull_distance_m must be > 0 (inf allowed), got {self.cull_distance_m}")

    @property
    def vertical_fov_rad(self) -> float:
        """Vertical field of view implied by the square pixels [rad]."""
        return 2.0 * math.atan(math.tan(self.horizontal_fov_rad / 2.0) * self.height / self.width)


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics [px] in the form sensor_msgs/CameraInfo wants."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def P(self) -> np.ndarray:
        """3x4 projection for a monocular camera (Tx = Ty = 0)."""
        return np.hstack([self.K, np.zeros((3, 1))])


@dataclass
class CameraFrame:
    """One rendered frame. Arrays are (H, W, ...)."""

    rgb: np.ndarray                      # uint8 (H, W, 3)
    depth_m: np.ndarray                  # float32 (H, W), NaN = no return / out of [near, far]
    semantic: np.ndarray                 # uint8 (H, W), SemanticClass values
    plant_id: Optional[np.ndarray]       # int32 (H, W), -1 = not a plant; None unless asked for
    world_T_optical: np.ndarray          # the pose it was rendered from


# a level camera 1 m above the origin, looking along world +x
_WARM_UP_POSE = np.array([[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]])


# per scene its soil texture in compose_image's tiled layout (8 bytes a texel: built once, shared by the cameras)
_TILED_SOIL = weakref.WeakKeyDictionary()


class _FastBuffers:
    """Per-camera state of the numba renderer: the scene's instanced plants and z-buffers per thread."""

    def __init__(self, scene: SensorScene, width: int, height: int) -> None:
        import numba
        self.plants = scene.fast_plants
        tex, *rest = scene.background_layer()
        if scene not in _TILED_SOIL:
            _TILED_SOIL[scene] = tile_texture(tex)
        self.background = (_TILED_SOIL[scene], tex.shape[1], tex.shape[0], *rest)
        threads = numba.get_num_threads()
        self.zbuf = np.zeros((threads, height, width), np.float32)     # 1/z [1/m], 0 = empty
        self.ibuf = np.zeros((threads, height, width), np.int32)       # global triangle id
        self.scratch = np.zeros((threads, 6, max(1, self.plants.max_model_verts)))   # see draw_plants


class CameraModel:
    """Renders one camera of a ``SensorScene``.

    ``render(world_T_optical)`` -> ``CameraFrame``; ``point_cloud(frame)`` ->
    (xyz, rgb) in the optical frame; ``intrinsics()`` for CameraInfo.
    With the pybullet renderers each camera owns a render client;
    ``last_render_stats`` tells how many plants were drawn and how many
    bodies were added/removed (always 0 for 'numba'). The numba renderer
    renders one warm-up frame in the constructor (compiles the kernels on
    the very first use, ~10-60 s; later processes load them from the cache).
    """

    def __init__(self, scene: SensorScene, config: CameraConfig = CameraConfig()) -> None:
        require_instance("scene", scene, SensorScene)
        require_instance("config", config, CameraConfig)
        self.scene = scene
        self.config = config
        self._intr = self._make_intrinsics()
        w, h = config.width, config.height
        u = (np.arange(w, dtype=np.float32) - self._intr.cx) / self._intr.fx
        v = (np.arange(h, dtype=np.float32) - self._intr.cy) / self._intr.fy
        self._ray_x = u                               # (W,) x/z per column
        self._ray_y = v                               # (H,) y/z per row
        self._ray_norm = np.sqrt(u[None, :] ** 2 + v[:, None] ** 2 + 1.0).astype(np.float32)
        projection = list(pb.computeProjectionMatrixFOV(
            fov=math.degrees(config.vertical_fov_rad), aspect=w / h, nearVal=config.near_m, farVal=config.far_m))
        # TinyRenderer samples pixel i at screen x = i of the viewport (NDC -1 .. 1 -> 0 .. W), which puts
        # the optical axis at column W / 2 and row H / 2 - 1 of the returned image (measured), half a pixel
        # off the principal point (W - 1) / 2, (H - 1) / 2 published in CameraInfo. An off-centre frustum
        # (constant NDC offsets of -1/W in x and -1/H in y, entries (0, 2) and (1, 2) of the column-major
        # GL matrix) moves the image onto the published intrinsics.
        projection[8] += 1.0 / w
        projection[9] += 1.0 / h
        self._projection = projection
        self._rng = np.random.default_rng(config.seed)
        self.last_render_stats = {"plants": 0, "added": 0, "removed": 0}
        self._client = None
        self._fast = None
        if config.renderer == "numba":
            self.renderer = "numba"
            self._fast = _FastBuffers(scene, w, h)
            self.render(_WARM_UP_POSE)          # compile or load the kernels now, not at the first reading
            self.last_render_stats = {"plants": 0, "added": 0, "removed": 0}
        else:
            self._client = scene.new_render_client(config.renderer)
            self.renderer = self._client.renderer

    def _make_intrinsics(self) -> CameraIntrinsics:
        c = self.config
        f = (c.width / 2.0) / math.tan(c.horizontal_fov_rad / 2.0)
        return CameraIntrinsics(c.width, c.height, f, f, (c.width - 1) / 2.0, (c.height - 1) / 2.0)

    def intrinsics(self) -> CameraIntrinsics:
        return self._intr

    @staticmethod
    def _view_matrix(world_T_optical: np.ndarray) -> list:
        """pybullet (OpenGL, column-major) view matrix of an optical-frame pose."""
        world_T_gl = world_T_optical @ np.diag([1.0, -1.0, -1.0, 1.0])   # GL: y up, looks along -z
        view = np.linalg.inv(world_T_gl)
        return view.T.ravel().tolist()

    def render(self, world_T_optical: np.ndarray, visibility: Optional[BollVisibility] = None) -> CameraFrame:
        """Render RGB, metric depth and semantics from a world_T_optical pose.

        visibility: which bolls to leave out (default: the scene's snapshot now).
        """
        pose = check_pose("world_T_optical", world_T_optical)
        cfg, scene = self.config, self.scene
        hidden = (visibility or scene.visibility).hidden
        tan_h = math.tan(cfg.horizontal_fov_rad / 2.0)
        tan_v = math.tan(cfg.vertical_fov_rad / 2.0)
        if self._fast is not None:
            visible, z_near = scene.plants_in_view_depth(pose, tan_h, tan_v, min(cfg.cull_distance_m, cfg.far_m))
            return self._render_numba(pose, visible, z_near, hidden)
        wanted = scene.plants_in_view(pose, tan_h, tan_v, min(cfg.cull_distance_m, cfg.far_m))
        added, removed = self._client.sync(wanted, hidden)
        self.last_render_stats = {"plants": len(wanted), "added": added, "removed": removed}
        sc = scene.config
        light = scene.config.sun_direction * 100.0
        _, _, rgba, depth_buf, seg = pb.getCameraImage(
            cfg.width, cfg.height, viewMatrix=self._view_matrix(pose), projectionMatrix=self._projection,
            lightDirection=light.tolist(), lightColor=list(sc.light_rgb), lightDistance=100.0,
            shadow=int(sc.shadows), lightAmbientCoeff=sc.ambient_coeff, lightDiffuseCoeff=sc.diffuse_coeff,
            lightSpecularCoeff=sc.specular_coeff, renderer=self._client.renderer_flag,
            flags=pb.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX, physicsClientId=self._client.client)
        rgba = np.asarray(rgba, dtype=np.uint8).reshape(cfg.height, cfg.width, 4)
        depth_buf = np.asarray(depth_buf, dtype=np.float32).reshape(cfg.height, cfg.width)
        seg = np.asarray(seg, dtype=np.int32).reshape(cfg.height, cfg.width)
        drawn = seg >= 0
        # OpenGL depth buffer d in [0, 1] -> eye-space distance along the optical axis
        n, f = cfg.near_m, cfg.far_m
        depth = (f * n / (f - (f - n) * depth_buf)).astype(np.float32)
        bg_rgb, bg_depth, bg_sem = scene.ground_and_sky(pose, self._intr.K, cfg.width, cfg.height, self._ray_norm)
        rgb = np.where(drawn[..., None], rgba[..., :3], bg_rgb)
        depth = np.where(drawn, depth, bg_depth)
        link_plus_one = np.clip(seg >> 24, 0, len(scene.link_semantic_lut) - 1)
        semantic = np.where(drawn, scene.link_semantic_lut[link_plus_one], bg_sem).astype(np.uint8)
        plant_id = None
        if cfg.plant_id_image:
            lut = self._client.plant_of_body
            body = np.clip(seg & 0xFFFFFF, 0, len(lut) - 1)
            plant_id = np.where(drawn, lut[body], -1).astype(np.int32)
        if cfg.depth_noise_std_m > 0.0:
            depth = depth + self._rng.normal(0.0, cfg.depth_noise_std_m, depth.shape).astype(np.float32)
        if cfg.rgb_noise_std > 0.0:
            noisy = rgb.astype(np.float32) + self._rng.normal(0.0, cfg.rgb_noise_std, rgb.shape)
            rgb = np.clip(noisy, 0, 255).astype(np.uint8)
        depth = np.where((depth >= n) & (depth <= f), depth, np.nan).astype(np.float32)
        return CameraFrame(rgb=np.ascontiguousarray(rgb), depth_m=depth, semantic=semantic,
                           plant_id=plant_id, world_T_optical=pose)

    def _levels_of_detail(self, visible: np.ndarray, z_near: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Per visible plant the model slot to draw and its first global triangle id.

        The coarsest level whose outline error bound, seen at the depth of the
        plant's nearest bounding-sphere point, is at most ``lod_max_error_px``.
        """
        inst = self._fast.plants
        model = inst.plant_model[visible]
        if self.config.lod_max_error_px <= 0.0 or len(visible) == 0:
            return model, inst.plant_gbase[visible]
        # largest error [m] allowed at each plant's depth; levels are ordered fine to coarse
        allowed_m = np.where(z_near > 0.0, self.config.lod_max_error_px * z_near / self._intr.fx, 0.0)
        level = np.zeros(len(visible), dtype=np.int64)
        for k in range(1, inst.LEVELS):
            level = np.where(inst.level_error_m[k, model] <= allowed_m, k, level)
        n_plants = self.last_render_stats["plants"]        # counted over the plants, not their bolls
        self.last_render_stats["simplified"] = int(np.count_nonzero(level[:n_plants] == inst.LEVELS - 1))
        self.last_render_stats["middle"] = int(np.count_nonzero((level[:n_plants] > 0)
                                                                & (level[:n_plants] < inst.LEVELS - 1)))
        return level * inst.model_count + model, inst.level_gbase[level, visible]

    def _render_numba(self, pose: np.ndarray, visible: np.ndarray, z_near: np.ndarray,
                      hidden: np.ndarray) -> CameraFrame:
        cfg, fb = self.config, self._fast
        # the visible plants' bolls that are still on them, as instances after the plants (each at its plant's depth)
        bolls, owner = self.scene.visible_bolls(visible, hidden)
        self.last_render_stats = {"plants": len(visible), "bolls": len(bolls), "added": 0, "removed": 0,
                                  "simplified": 0, "middle": 0}
        visible = np.concatenate([visible, self.scene.split.plant_count + bolls])
        z_near = np.concatenate([z_near, z_near[owner]])
        inst = fb.plants
        slot, gbase = self._levels_of_detail(visible, z_near)
        rot = pose[:3, :3].T                                  # optical_R_world
        trans = -rot @ pose[:3, 3]
        intr = self._intr
        draw_plants(visible, slot, gbase, inst.plant_pose,
                     inst.model_vbase, inst.model_vcount, inst.draw_base, inst.draw_count, inst.model_xyz, inst.draw_faces,
                     inst.draw_local, inst.draw_twin, rot, trans, intr.fx, intr.fy, intr.cx, intr.cy,
                     cfg.near_m, cfg.far_m, fb.zbuf, fb.ibuf, fb.scratch)
        rgb = np.empty((cfg.height, cfg.width, 3), np.uint8)
        depth = np.empty((cfg.height, cfg.width), np.float32)
        semantic = np.empty((cfg.height, cfg.width), np.uint8)
        plant_id = np.empty((cfg.height, cfg.width), np.int32)
        tex, tex_w, tex_h, x0, y0, rx, ry, sky = fb.background
        compose_image(fb.zbuf, fb.ibuf, inst.g_rgb, inst.g_semantic, inst.g_plant, np.ascontiguousarray(pose[:3, :3]),
                 np.ascontiguousarray(pose[:3, 3]), intr.fx, intr.fy, intr.cx, intr.cy, cfg.near_m, cfg.far_m,
                 tex, tex_w, tex_h, x0, y0, rx, ry, sky, int(SemanticClass.GROUND), int(SemanticClass.SKY),
                 rgb, depth, semantic, plant_id)
        if cfg.depth_noise_std_m > 0.0:
            depth = depth + self._rng.normal(0.0, cfg.depth_noise_std_m, depth.shape).astype(np.float32)
            with np.errstate(invalid="ignore"):
                depth = np.where((depth >= cfg.near_m) & (depth <= cfg.far_m), depth, np.nan).astype(np.float32)
        if cfg.rgb_noise_std > 0.0:
            noisy = rgb.astype(np.float32) + self._rng.normal(0.0, cfg.rgb_noise_std, rgb.shape)
            rgb = np.clip(noisy, 0, 255).astype(np.uint8)
        return CameraFrame(rgb=rgb, depth_m=depth, semantic=semantic,
                           plant_id=plant_id if cfg.plant_id_image else None, world_T_optical=pose)

    def point_cloud(self, frame: CameraFrame) -> Tuple[np.ndarray, np.ndarray]:
        """Back-project a frame: xyz (N, 3) float32 in the optical frame [m], rgb (N, 3) uint8.

        Keeps pixels with cloud_min_m <= depth <= cloud_max_m, every
        ``cloud_stride``-th pixel in u and v, in row-major pixel order
        (the columns of ``point_cloud_xyzrgb``).
        """
        packed, colours = self.point_cloud_xyzrgb(frame)
        return np.ascontiguousarray(packed[:, :3]), colours

    def point_cloud_xyzrgb(self, frame: CameraFrame) -> Tuple[np.ndarray, np.ndarray]:
        """The frame's cloud packed as PointCloud2 wants it, and its colours.

        Returns packed (N, 4) float32: columns x, y, z [m] (optical frame)
        and, in the fourth, the bits of PCL's packed colour 0x00RRGGBB (read
        it with ``.view(np.uint32)``), so that ``packed.tobytes()`` is the
        message's data for fields x, y, z, rgb at offsets 0, 4, 8, 12
        (little-endian, point_step 16); and rgb (N, 3) uint8. One compiled
        pass fills both.
        """
        cfg = self.config
        if frame.depth_m.shape != (cfg.height, cfg.width) or frame.rgb.shape != (cfg.height, cfg.width, 3):
            raise ValueError(f"frame has shapes {frame.depth_m.shape} / {frame.rgb.shape}, camera is "
                             f"{cfg.height}x{cfg.width}")
        depth = np.ascontiguousarray(frame.depth_m, dtype=np.float32)
        rgb = np.ascontiguousarray(frame.rgb, dtype=np.uint8)
        lo, hi, stride = np.float32(cfg.cloud_min_m), np.float32(cfg.cloud_max_m), int(cfg.cloud_stride)
        # room for every kept pixel: one pass instead of counting first; the returned arrays are the
        # first n rows (views; the untouched tail of a large np.empty is never paged in)
        room = (-(-cfg.height // stride)) * (-(-cfg.width // stride))
        out = np.empty((room, 4), np.uint32)
        colours = np.empty((room, 3), np.uint8)
        n = fill_cloud_xyzrgb(depth, rgb, self._ray_x, self._ray_y, stride, lo, hi, out.view(np.float32), out,
                               colours)
        return out[:n].view(np.float32), colours[:n]
