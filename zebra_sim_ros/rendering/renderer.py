"""The renderer: one world loaded once, zebras posed per frame, three outputs per camera view.

Per view it returns RGB (8-bit sRGB), depth along the optical axis in metres (float32; +inf where the ray
meets only sky, REP 118) and the instance mask (uint16: zebra id + 1, 0 for anything that is not a zebra),
all three from the same rasterisation, so they agree pixel for pixel. Anti-aliasing (FXAA) touches RGB only.
A camera with lens distortion (``RenderOptions.distortion``) is rendered as an ideal pinhole on its
:class:`~zebra_sim_ros.geometry.lens.LensCanvas` and resampled: RGB bilinearly, depth and ids at the nearest canvas
pixel, so they still agree pixel for pixel.

Cost control on a CPU: the terrain is drawn in 64 m tiles at 1 m resolution near the camera and 4 m
farther away, tiles and vegetation outside the view are culled, grass is drawn only near the camera,
zebras far away use the low-detail mesh, and only vegetation and zebras cast shadows (the terrain shades
itself by its normal). Each view has its own shadow map fitted to the ground it sees.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import ParameterError
from zebra_sim_ros.geometry.camera import PinholeCamera
from zebra_sim_ros.geometry.lens import Distortion
from zebra_sim_ros.messages import GroundLook, Lighting, SensorDraw, Weather
from zebra_sim_ros.rendering import shaders
from zebra_sim_ros.rendering.gl import create_context
from zebra_sim_ros.rendering.ground import contact_map, surface_from_colours, vegetation_occlusion
from zebra_sim_ros.world.world import World
from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.coat_store import CoatStore

FloatArray = NDArray[np.float64]
TILE_M = 64
COAT_LAYERS_FIRST = 64
"""Coat layers a renderer starts with: mipmaps are built over every layer of the array each frame that brings new
coats, so an array sized to the coats in use (doubled as it fills, and started again at layer 0 by a frame that
shows none of the coats it holds) costs a fraction of one of ``max_coats``."""


@dataclass(frozen=True)
class RenderOptions:
    """How to render. Sizes in pixels, distances in metres."""

    width: int = 1280
    height: int = 720
    hfov_deg: float = 80.0
    shadows: bool = True
    shadow_size: int = 2048
    shadow_radius_m: float = 120.0
    antialias: bool = True
    exposure: float = 1.2
    near_m: float = 0.1
    far_m: float = 4000.0
    grass_distance_m: float = 45.0
    bush_distance_m: float = 400.0
    terrain_detail_distance_m: float = 180.0
    zebra_detail_distance_m: float = 35.0
    coat_size: int = 256
    max_coats: int = 1024  # coat layers at most (the array starts at COAT_LAYERS_FIRST and doubles as it fills;
    # a frame of new animals starts it again at layer 0)
    detail: bool = True  # procedural ground detail (grass tufts, soil, stones, micro-relief) and the photographic coat
    # shading (contrast, belly, dust, sheen); False: flat ground colours and the coat texture as it is
    contact_shadows: bool = True  # soft occlusion on the ground under every animal
    coat_store: bool = False  # coats read from and written to the cache root's coat store (coat_store.CoatStore),
    # shared by every process (the camera nodes: three render the same animals); False: each coat baked in memory
    distortion: Distortion = field(default_factory=Distortion)  # the lens's (none: an ideal pinhole)

    @property
    def camera(self) -> PinholeCamera:
        """The camera these options render (with its lens)."""
        return PinholeCamera(self.width, self.height, self.hfov_deg, self.distortion)

    def check(self) -> None:
        """Raise :class:`ParameterError` for values outside their range (or a lens that folds over in the image)."""
        _ = self.camera.ideal  # the lens's canvas, and the pinhole it is drawn with
        if not 256 <= self.shadow_size <= 8192:
            raise ParameterError("shadow_size", self.shadow_size, "256..8192 px")
        if not 0.001 <= self.near_m < self.far_m:
            raise ParameterError("near_m", self.near_m, f"0.001..far_m ({self.far_m})")
        if self.coat_size not in (64, 128, 256, 512, 1024):
            raise ParameterError("coat_size", self.coat_size, "64, 128, 256, 512 or 1024 texels")
        if not 1 <= self.max_coats <= 4096:
            raise ParameterError("max_coats", self.max_coats, "1..4096 layers")


@dataclass(frozen=True)
class ZebraSet:
    """Placed zebras to draw: ids (pool indices), library morph indices and global frames, scale,
    asset-to-map rotation (N, 3, 3), position (N, 3), coat seeds."""

    ids: NDArray[np.int64]
    morph: NDArray[np.int64]
    global_frame: NDArray[np.int64]
    scale: FloatArray
    rotation: FloatArray
    position: FloatArray
    coat_seed: NDArray[np.int64]

    @property
    def count(self) -> int:
        """Number of zebras."""
        return int(len(self.ids))


@dataclass(frozen=True)
class CameraView:
    """Where a camera is: position in map (m) and ``r_optical`` (columns: optical x, y, z in map)."""

    name: str
    position: FloatArray
    r_optical: FloatArray


@dataclass
class RenderedView:
    """One camera's images; ``K`` is the pinhole intrinsic matrix the images follow, ``D`` the lens's plumb_bob
    distortion coefficients (zeros: none)."""

    name: str
    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    instances: NDArray[np.uint16]
    K: FloatArray
    timings: dict[str, float] = field(default_factory=dict)
    sensor: SensorDraw | None = None  # the camera model applied to ``rgb`` (None: the renderer's clean image)
    D: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)


def perspective(cam: PinholeCamera, near: float, far: float) -> FloatArray:
    """OpenGL projection of a pinhole camera (principal point at the centre, square pixels)."""
    fx = cam.fx
    return np.array([
        [2 * fx / cam.width, 0, 0, 0],
        [0, 2 * fx / cam.height, 0, 0],
        [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
        [0, 0, -1, 0],
    ])


def view_matrix(position: FloatArray, r_optical: FloatArray) -> FloatArray:
    """Map to OpenGL eye coordinates (x right, y up, looking down -z) for an optical frame pose."""
    gl_from_optical = np.diag([1.0, -1.0, -1.0])
    m = np.eye(4)
    m[:3, :3] = gl_from_optical @ r_optical.T
    m[:3, 3] = -m[:3, :3] @ position
    return m


def _frustum_planes(view_proj: FloatArray) -> FloatArray:
    """(6, 4) planes (a, b, c, d), inside where a x + b y + c z + d >= 0, normalised."""
    m = view_proj
    planes = np.array([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]])
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def _spheres_visible(planes: FloatArray, centres: FloatArray, radii: FloatArray) -> NDArray[np.bool_]:
    d = centres @ planes[:, :3].T + planes[:, 3]
    return np.asarray(np.all(d >= -radii[:, None], axis=1))


def _gl(m: FloatArray) -> bytes:
    """A 4x4 matrix as GLSL expects it (column-major float32)."""
    return np.asarray(m, dtype=np.float32).T.tobytes()


def _vertex_normals(v: FloatArray, f: NDArray[np.int64]) -> NDArray[np.float32]:
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    # Two-sided cards (grass blades) cancel out: light them like the ground they grow from.
    n = np.where(length > 1e-9, n / np.maximum(length, 1e-12), np.array([0.0, 0.0, 1.0]))
    return n.astype(np.float32)


def unweld_uvs(faces: NDArray[np.int64], uv: NDArray[np.float32]) -> tuple[NDArray[np.int64], NDArray[np.float32],
                                                                            NDArray[np.int32]]:
    """Per-vertex UVs from face-varying ones (faces (F, 3), uv (F, 3, 2)): the source vertex of each new vertex,
    the uv of each new vertex and the new faces (F, 3) int32. A vertex is split only where its UVs differ (the
    texture seam), so a posed vertex array indexed by the sources is all a draw needs."""
    q = np.round(uv.reshape(-1, 2) * 65536).astype(np.int64)
    key = faces.reshape(-1) * (1 << 40) + q[:, 0] * (1 << 20) + q[:, 1]
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    src = faces.reshape(-1)[first]
    return src, uv.reshape(-1, 2)[first].astype(np.float32), inverse.reshape(-1, 3).astype(np.int32)




class Renderer:
    """Renders views of one world with zebras; create once, call :meth:`render` per frame."""

    def __init__(self, world: World, library: ZebraLibrary, options: RenderOptions | None = None) -> None:
        self.options = options or RenderOptions()
        self.options.check()
        self.world = world
        self.library = library
        self.camera = self.options.camera
        self.canvas = self.camera.ideal  # what is drawn: the camera itself, or its lens's ideal canvas
        self.weather = Weather()
        t0 = time.perf_counter()
        self.ctx, self.info = create_context()
        ctx = self.ctx
        o = self.options
        self.p_terrain = ctx.program(vertex_shader=shaders.TERRAIN_VS, fragment_shader=shaders.TERRAIN_FS)
        self.p_veg = ctx.program(vertex_shader=shaders.VEG_VS, fragment_shader=shaders.VEG_FS)
        self.p_zebra = ctx.program(vertex_shader=shaders.ZEBRA_VS, fragment_shader=shaders.ZEBRA_FS)
        self.p_sky = ctx.program(vertex_shader=shaders.SKY_VS, fragment_shader=shaders.SKY_FS)
        self.p_fxaa = ctx.program(vertex_shader=shaders.FXAA_VS, fragment_shader=shaders.FXAA_FS)
        self.p_dveg = ctx.program(vertex_shader=shaders.DEPTH_VEG_VS, fragment_shader=shaders.DEPTH_FS)
        self.p_dzebra = ctx.program(vertex_shader=shaders.DEPTH_ZEBRA_VS, fragment_shader=shaders.DEPTH_FS)
        self.empty_vao = ctx.vertex_array(self.p_sky, [])
        self.fxaa_vao = ctx.vertex_array(self.p_fxaa, [])
        # Framebuffers: colour, depth in metres, instance id, and a depth buffer.
        size = (self.canvas.width, self.canvas.height)
        self.t_color = ctx.texture(size, 4)
        self.t_color.filter = (ctx.LINEAR, ctx.LINEAR)
        self.t_depth = ctx.texture(size, 1, dtype="f4")
        self.t_id = ctx.texture(size, 1, dtype="u4")
        self.zbuf = ctx.depth_renderbuffer(size)
        self.fbo = ctx.framebuffer([self.t_color, self.t_depth, self.t_id], self.zbuf)
        self.t_final = ctx.texture(size, 4)
        self.fbo_final = ctx.framebuffer([self.t_final])
        self.shadow_tex = ctx.depth_texture((o.shadow_size, o.shadow_size))
        self.shadow_tex.compare_func = "<="
        self.shadow_tex.filter = (ctx.LINEAR, ctx.LINEAR)
        self.fbo_shadow = ctx.framebuffer(depth_attachment=self.shadow_tex)
        self._upload_terrain()
        self._upload_vegetation()
        self._upload_zebra_templates()
        self.coats = self._coat_array(min(COAT_LAYERS_FIRST, o.max_coats))
        self._coat_layer: dict[tuple[int, int], int] = {}
        self.coat_store = CoatStore(library.root.parent, enabled=o.coat_store)
        self.setup_seconds = time.perf_counter() - t0

    # -- static uploads --------------------------------------------------------------------------
    def _upload_terrain(self) -> None:
        ctx, t = self.ctx, self.world.terrain
        h = t.heights.astype(np.float64)
        ny, nx = h.shape
        dx, dy = np.gradient(h, t.resolution)
        normal = np.stack([-dx, -dy, np.ones_like(h)], axis=-1)
        normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
        gc = self.world.ground_colors()
        if self.options.detail:  # ambient occlusion under trees and bushes, baked once (they do not move)
            gc = gc * vegetation_occlusion(self.world)[..., None]
        self.ground_mean = tuple(float(v) for v in gc.reshape(-1, 3).mean(axis=0))
        # Alpha: the water depth (m; negative above the water line, -2 where a world has no water).
        water = self.world.water if self.world.water is not None else np.full(gc.shape[:2], -2.0)
        rgba = np.concatenate([gc, np.clip(water, -2.0, 50.0)[..., None]], axis=-1)
        self.t_ground = ctx.texture((nx, ny), 4, np.ascontiguousarray(rgba, dtype=np.float32).tobytes(), dtype="f4")
        self.t_ground.filter = (ctx.LINEAR, ctx.LINEAR)
        self.t_ground.repeat_x = self.t_ground.repeat_y = False
        surf = self._surface_weights(gc)
        self.t_surface = ctx.texture((nx, ny), 4, surf.tobytes(), dtype="f4")
        self.t_surface.filter = (ctx.LINEAR, ctx.LINEAR)
        self.t_surface.repeat_x = self.t_surface.repeat_y = False
        self.t_contact = ctx.texture((1, 1), 1, np.ones(1, dtype=np.float32).tobytes(), dtype="f4")
        self.contact_xform = (0.0, 0.0, 1.0, 1.0)
        x0, y0, x1, y1 = t.bounds
        self.ground_xform = (x0, y0, 1.0 / (x1 - x0 + t.resolution) , 1.0 / (y1 - y0 + t.resolution))
        step_per_tile = max(1, int(round(TILE_M / t.resolution)))
        self.tiles: list[tuple[FloatArray, float, dict[int, object]]] = []
        for j0 in range(0, ny - 1, step_per_tile):
            for i0 in range(0, nx - 1, step_per_tile):
                j1, i1 = min(j0 + step_per_tile, ny - 1), min(i0 + step_per_tile, nx - 1)
                lods = {}
                for lod, stride in ((0, 1), (1, 4)):
                    lods[lod] = self._tile_vao(h, normal, i0, i1, j0, j1, stride)
                cx = x0 + (i0 + i1) / 2 * t.resolution
                cy = y0 + (j0 + j1) / 2 * t.resolution
                sub = h[j0:j1 + 1, i0:i1 + 1]
                centre = np.array([cx, cy, (sub.max() + sub.min()) / 2])
                radius = float(np.hypot((i1 - i0) * t.resolution, (j1 - j0) * t.resolution) / 2
                               + (sub.max() - sub.min()) / 2 + 2)
                self.tiles.append((centre, radius, lods))
        # An apron beyond the terrain's edge, so the world does not end at the horizon.
        edge = float(np.concatenate([h[0], h[-1], h[:, 0], h[:, -1]]).mean())
        big = 6000.0
        ring = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0 - big, y0 - big], [x1 + big, y0 - big],
                         [x1 + big, y1 + big], [x0 - big, y1 + big]])
        verts = np.column_stack([ring, np.full(8, edge - 0.5)]).astype(np.float32)
        norms = np.tile(np.array([0, 0, 1], dtype=np.float32), (8, 1))
        idx = np.array([0, 4, 5, 0, 5, 1, 1, 5, 6, 1, 6, 2, 2, 6, 7, 2, 7, 3, 3, 7, 4, 3, 4, 0], dtype=np.int32)
        self.apron = ctx.vertex_array(self.p_terrain, [(ctx.buffer(np.hstack([verts, norms]).tobytes()),
                                                         "3f 3f", "in_pos", "in_normal")],
                                      ctx.buffer(idx.tobytes()))

    def _tile_vao(self, h: FloatArray, normal: FloatArray, i0: int, i1: int, j0: int, j1: int,
                  stride: int) -> object:
        t = self.world.terrain
        ii = np.unique(np.append(np.arange(i0, i1 + 1, stride), i1))
        jj = np.unique(np.append(np.arange(j0, j1 + 1, stride), j1))
        gi, gj = np.meshgrid(ii, jj)
        pos = np.stack([t.origin[0] + gi * t.resolution, t.origin[1] + gj * t.resolution, h[gj, gi]], -1)
        nrm = normal[gj, gi]
        ny, nx = gi.shape
        idx = np.arange(ny * nx).reshape(ny, nx)
        a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
        faces = [np.stack([a, b, c], 1), np.stack([a, c, d], 1)]
        verts = [pos.reshape(-1, 3)]
        norms = [nrm.reshape(-1, 3)]
        # Skirts hang 2 m down from the border, hiding cracks between tiles of different detail.
        border = np.concatenate([idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]])
        n0 = ny * nx
        drop = verts[0][border] - np.array([0, 0, 2.0])
        verts.append(drop)
        norms.append(norms[0][border])
        k = np.arange(len(border))
        top0, top1 = border, np.roll(border, -1)
        bot0, bot1 = n0 + k, n0 + np.roll(k, -1)
        faces += [np.stack([top0, bot0, bot1], 1), np.stack([top0, bot1, top1], 1)]
        data = np.hstack([np.concatenate(verts), np.concatenate(norms)]).astype(np.float32)
        ibo = self.ctx.buffer(np.concatenate(faces).astype(np.int32).tobytes())
        vbo = self.ctx.buffer(data.tobytes())
        return self.ctx.vertex_array(self.p_terrain, [(vbo, "3f 3f", "in_pos", "in_normal")], ibo)

    def _upload_vegetation(self) -> None:
        ctx = self.ctx
        self.veg: list[dict[str, object]] = []
        for name, inst in self.world.vegetation.items():
            if not len(inst) or name not in self.world.prototypes:
                continue
            v, f, c = self.world.prototypes[name]
            v64 = np.asarray(v, dtype=np.float64)
            n = _vertex_normals(v64, np.asarray(f, dtype=np.int64))
            vbo = ctx.buffer(np.hstack([v, n, c]).astype(np.float32).tobytes())
            ibo = ctx.buffer(np.asarray(f, dtype=np.int32).tobytes())
            cap = len(inst)
            ibuf = ctx.buffer(reserve=max(cap, 1) * 20, dynamic=True)
            vao = ctx.vertex_array(self.p_veg, [(vbo, "3f 3f 3f", "in_pos", "in_normal", "in_color"),
                                                (ibuf, "3f 1f 1f/i", "i_pos", "i_yaw", "i_scale")], ibo)
            dvao = ctx.vertex_array(self.p_dveg, [(vbo, "3f 36x", "in_pos"),
                                                  (ibuf, "3f 1f 1f/i", "i_pos", "i_yaw", "i_scale")], ibo)
            radius = float(np.linalg.norm(v64, axis=1).max())
            data = np.column_stack([inst.positions, inst.yaw, inst.scale]).astype(np.float32)
            limit = {"grass": self.options.grass_distance_m, "bush": self.options.bush_distance_m}.get(inst.kind, 1e9)
            self.veg.append({"name": name, "kind": inst.kind, "vao": vao, "dvao": dvao, "ibuf": ibuf, "data": data,
                             "radius": radius, "limit": limit, "casts": inst.kind != "grass"})

    def _upload_zebra_templates(self) -> None:
        ctx = self.ctx
        self.zebra_lod: dict[int, dict[str, object]] = {}
        for lod in (0, 1):
            src, uv, faces = unweld_uvs(self.library.faces(lod), self.library.uv(lod))
            uv_buf = ctx.buffer(uv.tobytes())
            ibo = ctx.buffer(faces.tobytes())
            inst = ctx.buffer(reserve=8 * 1024, dynamic=True)
            vao = ctx.vertex_array(self.p_zebra, [(uv_buf, "2f", "in_uv"), (inst, "1u 1f/i", "i_id", "i_layer")], ibo)
            dvao = ctx.vertex_array(self.p_dzebra, [], ibo)
            self.zebra_lod[lod] = {"src": src, "vao": vao, "dvao": dvao, "inst": inst, "verts": len(src),
                                   "ssbo": ctx.buffer(reserve=4, dynamic=True)}

    def _coat_array(self, layers: int) -> Any:
        """A texture array of ``layers`` coats, filtered as every coat is sampled. Its mipmaps are built once coats
        are written into it (:meth:`_layers`): built over the empty array, as they once were, they cost a tenth of a
        six-world ``generate``'s time and were built again before any was sampled."""
        s = self.options.coat_size
        arr = self.ctx.texture_array((s, s, layers), 3)
        arr.filter = (self.ctx.LINEAR_MIPMAP_LINEAR, self.ctx.LINEAR)
        return arr

    def _layers(self, zebras: ZebraSet, seen: NDArray[np.bool_]) -> NDArray[np.float32]:
        """Each zebra's coat layer; the coats not yet in the array come from the coat store (read or baked) in one
        call, so the processes that render the same animals share the baking, and the mipmaps are built again. Only
        the animals ``seen`` by some view of the frame get a coat: the others are culled from every pass (shadows
        included), so their layer (0) is never sampled and their coats are never baked."""
        idx = np.flatnonzero(seen)
        keys = [(int(zebras.morph[i]), int(zebras.coat_seed[i])) for i in idx]
        unique = list(dict.fromkeys(keys))
        new = [k for k in unique if k not in self._coat_layer]
        held, cap = len(self._coat_layer), self.options.max_coats
        none_held = held > 0 and len(new) == len(unique)  # a frame that shows none of the coats the array holds
        restart = held + len(new) > cap or (none_held and held + len(new) > self.coats.size[2])
        if restart:
            # More individuals than layers (rare), or a frame that shows none of the coats held and would grow the
            # array (``generate``: new animals every frame): its coats start again at layer 0. A coat's layer only
            # says where the shader finds it, so the pixels are the same; the array stays the size of a frame's
            # coats, not ``max_coats``, and so does the cost of its mipmaps.
            new = unique
            if len(new) > cap:
                raise ParameterError("max_coats", cap, f">= the {len(new)} individuals of a frame")
        names = self.library.morphs
        # the coats first: one that cannot be had (a morph the library lacks) leaves the array and its layers as they
        # were
        texs = self.coat_store.coats([(names[m], seed) for m, seed in new], self.options.coat_size)
        if restart:
            self._coat_layer.clear()
        need = len(self._coat_layer) + len(new)
        if need > self.coats.size[2]:  # full: doubled until the frame's coats fit, once, the coats held copied over
            size = self.coats.size[2]
            while size < need:
                size *= 2
            grown = self._coat_array(min(size, cap))
            if self._coat_layer:
                grown.write(self.coats.read(), viewport=(0, 0, 0, *self.coats.size))
            self.coats.release()
            self.coats = grown
        s = self.options.coat_size
        for key, tex in zip(new, texs, strict=True):
            layer = len(self._coat_layer)
            self.coats.write(np.ascontiguousarray(tex[::-1]).tobytes(), viewport=(0, 0, layer, s, s, 1))
            self._coat_layer[key] = layer
        if new:
            self.coats.build_mipmaps()
        layers = np.zeros(zebras.count, dtype=np.float32)
        layers[idx] = [self._coat_layer[k] for k in keys]
        return layers

    # -- per frame -------------------------------------------------------------------------------
    def render(self, zebras: ZebraSet, lighting: Lighting, views: list[CameraView],
               ground: GroundLook | None = None, weather: Weather | None = None) -> list[RenderedView]:
        """Render every view of one frame (``ground``: the landscape's look, None = as authored; ``weather``: the
        sky, None = clear; the plain look, ``detail`` off, always renders a clear sky). The renderer's GL context is
        made current for the frame (and the one current before restored): a process may hold several renderers."""
        with self.ctx:
            return self._render_frame(zebras, lighting, views, ground, weather)

    def _render_frame(self, zebras: ZebraSet, lighting: Lighting, views: list[CameraView],
                      ground: GroundLook | None, weather: Weather | None) -> list[RenderedView]:
        g = ground or GroundLook()
        self.weather = (weather or Weather()) if self.options.detail else Weather()
        self.p_terrain["u_ground_tint"].value = g.tint
        self.p_terrain["u_ground_desat"].value = g.desaturation
        self.p_veg["u_veg_tint"].value = g.vegetation_tint
        self.p_veg["u_detail"].value = 1.0 if self.options.detail else 0.0
        # one culling per view, for the coats (those of animals no view sees are never baked) and the draws alike
        frusta = [self._frustum(v) for v in views]
        in_view = [self._in_view(zebras, planes) for _, planes in frusta]
        layers = self._layers(zebras, np.logical_or.reduce(in_view, axis=0) if in_view
                              else np.zeros(zebras.count, dtype=bool))
        self._upload_contact(zebras)
        if "u_detail" in self.p_zebra:
            self.p_zebra["u_detail"].value = 1.0 if self.options.detail else 0.0
        if "u_ground_z" in self.p_zebra:
            self.p_zebra["u_ground_z"].value = float(np.median(zebras.position[:, 2])) if zebras.count else 0.0
        return [self._render_view(zebras, layers, lighting, v, vp, planes, vis)
                for v, (vp, planes), vis in zip(views, frusta, in_view, strict=True)]

    def _surface_weights(self, colours: NDArray[np.float32]) -> NDArray[np.float32]:
        """The world's surface classes per terrain sample (grass, soil, rock, wet), or ones read off the colours."""
        surface = getattr(self.world, "ground_surface", None)
        weights = surface() if callable(surface) else surface_from_colours(colours)
        return np.ascontiguousarray(weights, dtype=np.float32)

    def _upload_contact(self, zebras: ZebraSet) -> None:
        """This frame's contact shadows under the zebras (a texture over the herd; none when switched off)."""
        if not self.options.contact_shadows or not zebras.count:
            self.contact_xform = (0.0, 0.0, 0.0, 0.0)  # every ground point maps to uv 0: one texel of 1.0
            return
        cmap = contact_map(zebras.position, zebras.rotation[:, :2, 0], zebras.scale)
        ny, nx = cmap.values.shape
        if self.t_contact.size != (nx, ny):
            self.t_contact.release()
            self.t_contact = self.ctx.texture((nx, ny), 1, dtype="f4")
            self.t_contact.filter = (self.ctx.LINEAR, self.ctx.LINEAR)
            self.t_contact.repeat_x = self.t_contact.repeat_y = False
        self.t_contact.write(cmap.values.tobytes())
        self.contact_xform = cmap.xform

    def _zebra_buffers(self, zebras: ZebraSet, layers: NDArray[np.float32], sel: NDArray[np.int64],
                       lod: int) -> int:
        z = self.zebra_lod[lod]
        if len(sel) == 0:
            return 0
        posed = self.library.pose(zebras.morph[sel], zebras.global_frame[sel], zebras.scale[sel],
                                  zebras.rotation[sel], zebras.position[sel], lod=lod)
        data = np.ascontiguousarray(posed.vertices[:, z["src"]], dtype=np.float32)  # type: ignore[index]
        ssbo = z["ssbo"]
        if ssbo.size < data.nbytes:  # type: ignore[attr-defined]
            ssbo.orphan(data.nbytes)  # type: ignore[attr-defined]
        ssbo.write(data.tobytes())  # type: ignore[attr-defined]
        inst = np.zeros(len(sel), dtype=[("id", "<u4"), ("layer", "<f4")])
        inst["id"] = zebras.ids[sel] + 1
        inst["layer"] = layers[sel]
        buf = z["inst"]
        if buf.size < inst.nbytes:  # type: ignore[attr-defined]
            buf.orphan(inst.nbytes)  # type: ignore[attr-defined]
        buf.write(inst.tobytes())  # type: ignore[attr-defined]
        return len(sel)

    def _light_matrix(self, view: CameraView, lighting: Lighting) -> FloatArray:
        """Orthographic light view-projection covering the ground this view sees (up to shadow_radius_m)."""
        o = self.options
        fwd = view.r_optical[:, 2]
        ground = float(self.world.terrain.height_at(view.position[0], view.position[1]))
        height = max(view.position[2] - ground, 1.0)
        dist = height / max(-fwd[2], 0.05) if fwd[2] < 0 else o.shadow_radius_m
        centre = view.position + fwd * min(dist, o.shadow_radius_m * 0.8)
        centre[2] = float(self.world.terrain.height_at(centre[0], centre[1]))
        r = o.shadow_radius_m
        ld = np.array(lighting.light_direction)
        up = np.array([0.0, 0.0, 1.0]) if abs(ld[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
        zaxis = ld / np.linalg.norm(ld)
        xaxis = np.cross(up, zaxis)
        xaxis /= np.linalg.norm(xaxis)
        yaxis = np.cross(zaxis, xaxis)
        eye = centre + zaxis * 400.0
        view_m = np.eye(4)
        view_m[:3, :3] = np.stack([xaxis, yaxis, zaxis])
        view_m[:3, 3] = -view_m[:3, :3] @ eye
        near, far = 1.0, 800.0
        proj = np.array([[1 / r, 0, 0, 0], [0, 1 / r, 0, 0], [0, 0, -2 / (far - near), -(far + near) / (far - near)],
                         [0, 0, 0, 1]])
        return proj @ view_m

    def _render_view(self, zebras: ZebraSet, layers: NDArray[np.float32], lighting: Lighting,
                     view: CameraView, vp: FloatArray, planes: FloatArray, in_view: NDArray[np.bool_]) -> RenderedView:
        o = self.options
        times: dict[str, float] = {}
        t0 = time.perf_counter()
        pos = np.asarray(view.position, dtype=np.float64)
        counts = self._cull_zebras(zebras, layers, in_view, pos)
        veg_counts = self._cull_vegetation(planes, pos)
        times["prepare"] = time.perf_counter() - t0

        t1 = time.perf_counter()
        light_vp = self._light_matrix(view, lighting)
        use_shadow = o.shadows and lighting.light_direction[2] > 0.02
        if use_shadow:
            self._shadow_pass(light_vp, counts, veg_counts)
        times["shadow"] = time.perf_counter() - t1

        t2 = time.perf_counter()
        self.fbo.use()
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable(self.ctx.DEPTH_TEST)
        self.ctx.disable(self.ctx.CULL_FACE)
        self._set_view_uniforms(vp, light_vp, pos, view.r_optical[:, 2], lighting, use_shadow)
        self._draw_terrain(planes, pos)
        for g, n in zip(self.veg, veg_counts, strict=True):
            if n:
                g["vao"].render(instances=n)  # type: ignore[attr-defined]
        self.coats.use(location=3)
        self.p_zebra["u_coats"].value = 3
        self._draw_zebras(self.p_zebra, "vao", counts)
        self._draw_sky(vp, lighting)
        times["draw"] = time.perf_counter() - t2

        t3 = time.perf_counter()
        rgb, depth, id16 = self._read_images()
        times["read"] = time.perf_counter() - t3
        times["zebras_lod0"], times["zebras_lod1"] = counts[0], counts[1]
        return RenderedView(view.name, rgb, depth, id16, self.camera.K, times, D=self.camera.D)

    def _frustum(self, view: CameraView) -> tuple[FloatArray, FloatArray]:
        """The view-projection matrix of ``view`` and its frustum planes (:func:`_frustum_planes`)."""
        o = self.options
        vp = perspective(self.canvas, o.near_m, o.far_m) @ view_matrix(np.asarray(view.position, dtype=np.float64),
                                                                       view.r_optical)
        return vp, _frustum_planes(vp)

    @staticmethod
    def _in_view(zebras: ZebraSet, planes: FloatArray) -> NDArray[np.bool_]:
        """The animals whose bounding sphere (2.5 x scale + 0.5 m: any pose) reaches into the frustum ``planes``."""
        if not zebras.count:
            return np.zeros(0, dtype=bool)
        return _spheres_visible(planes, zebras.position, 2.5 * zebras.scale + 0.5)

    def _cull_zebras(self, zebras: ZebraSet, layers: NDArray[np.float32], vis: NDArray[np.bool_],
                     pos: FloatArray) -> dict[int, int]:
        """Fill each level of detail's buffers with the zebras ``vis`` marks in view (near: LOD 0, far: LOD 1);
        counts per LOD."""
        o = self.options
        counts = {0: 0, 1: 0}
        if zebras.count:
            d = np.linalg.norm(zebras.position - pos, axis=1)
            for lod, mask in ((0, d < o.zebra_detail_distance_m), (1, d >= o.zebra_detail_distance_m)):
                counts[lod] = self._zebra_buffers(zebras, layers, np.flatnonzero(vis & mask), lod)
        return counts

    def _cull_vegetation(self, planes: FloatArray, pos: FloatArray) -> list[int]:
        """Fill each prototype's instance buffer with the copies within its draw distance and in view; counts."""
        veg_counts = []
        for g in self.veg:
            data = g["data"]
            p = data[:, :3].astype(np.float64)  # type: ignore[index]
            keep = np.linalg.norm(p[:, :2] - pos[:2], axis=1) < g["limit"]  # type: ignore[operator]
            keep &= _spheres_visible(planes, p, g["radius"] * data[:, 4].astype(np.float64))  # type: ignore[index,operator]
            sel = data[keep]  # type: ignore[index]
            if len(sel):
                g["ibuf"].write(np.ascontiguousarray(sel).tobytes())  # type: ignore[attr-defined]
            veg_counts.append(len(sel))
        return veg_counts

    def _draw_zebras(self, prog: Any, vao: str, counts: dict[int, int]) -> None:
        """Draw the culled zebras of each level of detail with ``prog`` through their ``vao`` ("vao" or "dvao")."""
        for lod in (0, 1):
            if counts[lod]:
                z = self.zebra_lod[lod]
                z["ssbo"].bind_to_storage_buffer(0)  # type: ignore[attr-defined]
                prog["u_verts"].value = z["verts"]
                z[vao].render(instances=counts[lod])  # type: ignore[attr-defined]

    def _shadow_pass(self, light_vp: FloatArray, counts: dict[int, int], veg_counts: list[int]) -> None:
        """Render the shadow map: the depth of vegetation that casts shadows and of the zebras, seen from the sun."""
        self.fbo_shadow.use()
        self.fbo_shadow.clear(depth=1.0)
        self.ctx.enable(self.ctx.DEPTH_TEST)
        for prog in (self.p_dveg, self.p_dzebra):
            prog["u_light_view_proj"].write(_gl(light_vp))
        for g, n in zip(self.veg, veg_counts, strict=True):
            if n and g["casts"]:
                g["dvao"].render(instances=n)  # type: ignore[attr-defined]
        self._draw_zebras(self.p_dzebra, "dvao", counts)

    def _set_view_uniforms(self, vp: FloatArray, light_vp: FloatArray, pos: FloatArray, fwd: FloatArray,
                           lighting: Lighting, use_shadow: bool) -> None:
        """Camera, light, sky and exposure uniforms of every colour pass program."""
        sky, w = self.world.sky, self.weather
        light_rgb = np.array(lighting.light_rgb) * w.light_tint * lighting.light_intensity * sky.sun * 2.2
        ambient = np.array(lighting.ambient_rgb) * lighting.ambient_intensity * (sky.ambient / 0.35) * 1.6
        uniforms = {
            "u_view_proj": _gl(vp), "u_light_view_proj": _gl(light_vp),
            "u_cam_pos": pos.astype(np.float32).tobytes(), "u_cam_fwd": fwd.astype(np.float32).tobytes(),
            "u_light_dir": np.array(lighting.light_direction, dtype=np.float32).tobytes(),
            "u_light_rgb": light_rgb.astype(np.float32).tobytes(),
            "u_ambient_rgb": ambient.astype(np.float32).tobytes(),
            "u_horizon_rgb": (np.array(sky.horizon_rgb) * w.sky_tint).astype(np.float32).tobytes(),
            "u_zenith_rgb": (np.array(sky.zenith_rgb) * w.sky_tint).astype(np.float32).tobytes(),
            "u_cloud_offset": np.array(w.cloud_offset, dtype=np.float32).tobytes(),
        }
        self.shadow_tex.use(location=1)
        for prog in (self.p_terrain, self.p_veg, self.p_zebra, self.p_sky):
            for k, val in uniforms.items():
                if k in prog:
                    prog[k].write(val)
            for k, val2 in (("u_haze", sky.haze_per_m), ("u_exposure", self.options.exposure),
                            ("u_cloud_cover", w.cloud_cover)):
                if k in prog:
                    prog[k].value = float(val2)
            if "u_shadow" in prog:
                prog["u_shadow"].value = 1
            if "u_use_shadow" in prog:
                prog["u_use_shadow"].value = int(use_shadow)

    def _draw_terrain(self, planes: FloatArray, pos: FloatArray) -> None:
        """The terrain tiles in view (fine near the camera, coarse farther) and the apron around them."""
        self.t_ground.use(location=2)
        self.p_terrain["u_ground"].value = 2
        self.p_terrain["u_ground_xform"].value = self.ground_xform
        self.p_terrain["u_ground_mean"].value = self.ground_mean
        self.t_surface.use(location=4)
        self.p_terrain["u_surface"].value = 4
        self.t_contact.use(location=5)
        self.p_terrain["u_contact"].value = 5
        self.p_terrain["u_contact_xform"].value = self.contact_xform
        self.p_terrain["u_detail"].value = 1.0 if self.options.detail else 0.0
        for centre, radius, lods in self.tiles:
            if not _spheres_visible(planes, centre[None], np.array([radius]))[0]:
                continue
            near = np.linalg.norm(centre[:2] - pos[:2]) - radius < self.options.terrain_detail_distance_m
            lods[0 if near else 1].render()  # type: ignore[attr-defined]
        self.apron.render()

    def _draw_sky(self, vp: FloatArray, lighting: Lighting) -> None:
        """The sky where nothing else was drawn (at the far plane, depth test <=)."""
        ctx = self.ctx
        ctx.depth_func = "<="
        self.p_sky["u_inv_view_proj"].write(_gl(np.asarray(np.linalg.inv(vp), dtype=np.float64)))
        self.p_sky["u_sun_dir"].value = tuple(float(x) for x in lighting.sun_direction)
        self.p_sky["u_sun_visible"].value = 1.0 if lighting.sun_elevation_deg > -1 else 0.0
        self.empty_vao.render(vertices=3)
        ctx.depth_func = "<"

    def _read_images(self) -> tuple[NDArray[np.uint8], NDArray[np.float32], NDArray[np.uint16]]:
        """RGB (after FXAA when antialias is on), depth in metres (+inf for sky) and instance ids, rows top first;
        through the lens where it has distortion."""
        ctx, o = self.ctx, self.options
        w, h = self.canvas.width, self.canvas.height
        if o.antialias:
            self.fbo_final.use()
            ctx.disable(ctx.DEPTH_TEST)
            self.t_color.use(location=0)
            self.p_fxaa["u_src"].value = 0
            self.fxaa_vao.render(vertices=3)
            rgba = np.frombuffer(self.fbo_final.read(components=4, attachment=0), dtype=np.uint8)
        else:
            rgba = np.frombuffer(self.fbo.read(components=4, attachment=0), dtype=np.uint8)
        rgb = rgba.reshape(h, w, 4)[::-1, :, :3].copy()
        depth = np.frombuffer(self.fbo.read(components=1, attachment=1, dtype="f4"), dtype=np.float32)
        depth = depth.reshape(h, w)[::-1].copy()
        depth[depth <= 0] = np.inf
        ids = np.frombuffer(self.fbo.read(components=1, attachment=2, dtype="u4"), dtype=np.uint32)
        id16: NDArray[np.uint16] = ids.reshape(h, w)[::-1].astype(np.uint16)
        lens = self.camera.canvas
        if lens is not None:
            rgb = np.asarray(cv2.remap(rgb, lens.map_x, lens.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE),
                             dtype=np.uint8)
            depth = np.ascontiguousarray(lens.resample_nearest(depth))
            id16 = np.ascontiguousarray(lens.resample_nearest(id16))
        return rgb, depth, id16

    def release(self) -> None:
        """Free the GL context."""
        self.ctx.release()
