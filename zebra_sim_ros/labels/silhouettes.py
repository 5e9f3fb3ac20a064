"""Unoccluded silhouettes: how many pixels each zebra would cover if nothing stood in front of it.

Every zebra is rasterised alone, with the camera's own projection, into its own tile of an atlas: the
tile is the zebra's projected bounding box shifted by a whole number of pixels, so the GPU samples the very
same pixel centres as in the camera image, and the count is exact and consistent with the mask (a zebra's
visible pixels are always a subset of its silhouette). Tiles may reach outside the image, which gives the
in-frame fraction as well. Zebras are drawn with the same level of detail rule as the renderer.

A camera with lens distortion is drawn as the renderer draws it, on its lens's ideal canvas; each canvas pixel of
a silhouette then counts as the number of image pixels that show it (their nearest canvas pixel, as in the mask),
so the count is still exact and consistent with the mask; outside the image, where no image pixel shows the canvas,
it counts as the lens's area factor there (the part of a silhouette outside the image is then an estimate).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.geometry.camera import PinholeCamera, map_to_optical
from zebra_sim_ros.geometry.lens import LensCanvas
from zebra_sim_ros.rendering.gl import create_context
from zebra_sim_ros.rendering.renderer import ZebraSet, perspective, unweld_uvs, view_matrix
from zebra_sim_ros.zebra.asset import ZebraLibrary
from zebra_sim_ros.zebra.lod import DETAIL_DISTANCE_M, lod_of

_VS = """
#version 430
layout(std430, binding = 0) buffer Posed { float posed[]; };
uniform mat4 u_view_proj;
uniform int u_verts;
uniform vec2 u_image;   // camera image size, px
uniform vec2 u_atlas;   // atlas size, px
in vec2 i_offset;       // whole-pixel shift of this zebra's tile (image px, y down)
void main() {
    int k = (gl_InstanceID * u_verts + gl_VertexID) * 3;
    vec4 c = u_view_proj * vec4(posed[k], posed[k + 1], posed[k + 2], 1.0);
    // image pixel (edge coordinates, y down) = ((x/w + 1) / 2 * W, (1 - y/w) / 2 * H); shift; to atlas NDC
    vec2 pix = vec2((c.x + c.w) * 0.5 * u_image.x, (c.w - c.y) * 0.5 * u_image.y);   // times w
    vec2 at = pix + i_offset * c.w;
    gl_Position = vec4(at.x / u_atlas.x * 2.0 - c.w, c.w - at.y / u_atlas.y * 2.0, c.z, c.w);
}
"""
_FS = """
#version 430
out float f;
void main() { f = 1.0; }
"""


@dataclass(frozen=True)
class Coverage:
    """Per zebra (in the order asked): pixels of its silhouette inside the image, and in all (unclipped)."""

    in_image: NDArray[np.int64]
    total: NDArray[np.int64]


@lru_cache(maxsize=8)
def _lens_weights(camera: PinholeCamera) -> tuple[LensCanvas, NDArray[np.float64], NDArray[np.float64]] | None:
    """The lens's canvas, and what a canvas pixel of a silhouette counts in the image of a camera with a lens (None
    without one): inside the image (how many image pixels show it), and in all (that where the image shows it or its
    centre is in the image, else the lens's area factor: the part of a silhouette off the image is an estimate).
    Made once per camera model in a process (a counter per world or labeller shares them; read-only)."""
    lens = camera.canvas
    if lens is None:
        return None
    shown = lens.multiplicity().astype(np.float64)
    cols, rows = np.meshgrid(np.arange(lens.canvas_width), np.arange(lens.canvas_height))
    x, y = lens.normalised(cols, rows)
    in_image = camera.in_image(np.stack([x, y, np.ones_like(x)], axis=-1))
    weights = shown, np.where(in_image | (shown > 0), shown, lens.area_factor(x, y))
    for array in weights:
        array.flags.writeable = False
    return lens, *weights


def _shelf_pack(todo: list[int], w: NDArray[np.int64], h: NDArray[np.int64],
                atlas: int) -> tuple[dict[int, tuple[int, int]], list[int]]:
    """Shelf packing of tiles ``w x h`` (in ``todo`` order) into one atlas page: each placed tile's top-left
    corner, and the tiles that go to the next page."""
    place: dict[int, tuple[int, int]] = {}
    sx = sy = shelf = 0
    rest = []
    for i in todo:
        if sx + w[i] > atlas:
            sx, sy, shelf = 0, sy + shelf, 0
        if sy + h[i] > atlas:
            rest.append(i)
            continue
        place[i] = (sx, sy)
        sx += int(w[i])
        shelf = max(shelf, int(h[i]))
    return place, rest


class SilhouetteCounter:
    """Counts unoccluded silhouette pixels of zebras for one camera model."""

    def __init__(self, library: ZebraLibrary, camera: PinholeCamera, detail_distance_m: float = DETAIL_DISTANCE_M,
                 near_m: float = 0.1, far_m: float = 4000.0, atlas: int = 4096, ctx: Any = None) -> None:
        self.library, self.camera = library, camera
        self.canvas = camera.ideal  # the pinhole the silhouettes are drawn with (the renderer's)
        self.weights = _lens_weights(camera)
        self.detail_distance_m, self.near_m, self.far_m = detail_distance_m, near_m, far_m
        self.atlas = atlas
        self.ctx = ctx if ctx is not None else create_context()[0]
        self.owns_ctx = ctx is None
        self.lod: dict[int, dict[str, Any]] = {}
        with self.ctx as c:  # a shared context need not be the current one
            self.prog = c.program(vertex_shader=_VS, fragment_shader=_FS)
            self.tex = c.texture((atlas, atlas), 1, dtype="f1")
            self.fbo = c.framebuffer([self.tex])
            for lod in (0, 1):
                src, _, faces = unweld_uvs(library.faces(lod), library.uv(lod))
                inst = c.buffer(reserve=8 * 1024, dynamic=True)
                vao = c.vertex_array(self.prog, [(inst, "2f/i", "i_offset")], c.buffer(faces.tobytes()))
                self.lod[lod] = {"src": src, "vao": vao, "inst": inst, "ssbo": c.buffer(reserve=4, dynamic=True)}

    def count(self, zebras: ZebraSet, position: NDArray[np.float64], r_optical: NDArray[np.float64],
              which: NDArray[np.int64] | None = None) -> Coverage:
        """Silhouette pixel counts of ``zebras`` (or the subset ``which``) seen from a camera pose (in the image's
        pixels, through the lens), drawn with this counter's GL context current (the one before restored)."""
        with self.ctx:
            return self._count(zebras, position, r_optical, which)

    def _count(self, zebras: ZebraSet, position: NDArray[np.float64], r_optical: NDArray[np.float64],
               which: NDArray[np.int64] | None) -> Coverage:
        sel_all = np.arange(zebras.count) if which is None else np.asarray(which, dtype=np.int64)
        n = len(sel_all)
        in_image = np.zeros(n, dtype=np.int64)
        total = np.zeros(n, dtype=np.int64)
        if n == 0:
            return Coverage(in_image, total)
        cam = self.canvas
        vp = perspective(cam, self.near_m, self.far_m) @ view_matrix(position, r_optical)
        dist = np.linalg.norm(zebras.position[sel_all] - position, axis=1)
        self.prog["u_view_proj"].write(np.asarray(vp, dtype=np.float32).T.tobytes())
        self.prog["u_image"].value = (float(cam.width), float(cam.height))
        self.prog["u_atlas"].value = (float(self.atlas), float(self.atlas))
        levels = lod_of(dist, self.detail_distance_m)
        for lod in (0, 1):
            pick = np.flatnonzero(levels == lod)
            if len(pick):
                self._count_lod(zebras, sel_all[pick], lod, position, r_optical, in_image, total, pick)
        return Coverage(in_image, total)

    def _count_lod(self, zebras: ZebraSet, sel: NDArray[np.int64], lod: int, position: NDArray[np.float64],
                   r_optical: NDArray[np.float64], in_image: NDArray[np.int64], total: NDArray[np.int64],
                   slots: NDArray[np.int64]) -> None:
        cam, z = self.canvas, self.lod[lod]
        posed = self.library.pose(zebras.morph[sel], zebras.global_frame[sel], zebras.scale[sel],
                                  zebras.rotation[sel], zebras.position[sel], lod=lod)
        verts = np.ascontiguousarray(posed.vertices[:, z["src"]], dtype=np.float32)
        p = map_to_optical(verts.astype(np.float64), position, r_optical)  # (N, U, 3)
        front = p[..., 2] > self.near_m
        zs = np.where(front, p[..., 2], 1.0)
        u = cam.fx * p[..., 0] / zs + cam.width / 2  # edge coordinates
        v = cam.fx * p[..., 1] / zs + cam.height / 2
        big = 10 * max(cam.width, cam.height)
        u = np.where(front, np.clip(u, -big, big), np.nan)
        v = np.where(front, np.clip(v, -big, big), np.nan)
        ok: NDArray[np.bool_] = np.asarray(front.any(axis=1))
        x0 = np.floor(np.nanmin(np.where(ok[:, None], u, 0), axis=1)).astype(np.int64) - 2
        y0 = np.floor(np.nanmin(np.where(ok[:, None], v, 0), axis=1)).astype(np.int64) - 2
        x1 = np.ceil(np.nanmax(np.where(ok[:, None], u, 0), axis=1)).astype(np.int64) + 2
        y1 = np.ceil(np.nanmax(np.where(ok[:, None], v, 0), axis=1)).astype(np.int64) + 2
        w, h = np.minimum(x1 - x0, self.atlas), np.minimum(y1 - y0, self.atlas)
        todo = [i for i in np.argsort(-h) if ok[i]]  # tallest first: shelves pack well
        while todo:
            place, rest = _shelf_pack(todo, w, h, self.atlas)
            idx = np.array(sorted(place), dtype=np.int64)
            offs = np.array([[place[i][0] - x0[i], place[i][1] - y0[i]] for i in idx], dtype=np.float32)
            data = verts[idx]
            if z["ssbo"].size < data.nbytes:
                z["ssbo"].orphan(data.nbytes)
            z["ssbo"].write(data.tobytes())
            if z["inst"].size < offs.nbytes:
                z["inst"].orphan(offs.nbytes)
            z["inst"].write(offs.tobytes())
            self.fbo.use()
            self.fbo.clear(0.0)
            self.ctx.disable(self.ctx.DEPTH_TEST)
            self.ctx.disable(self.ctx.CULL_FACE)
            z["ssbo"].bind_to_storage_buffer(0)
            self.prog["u_verts"].value = len(z["src"])
            z["vao"].render(instances=len(idx))
            img = np.frombuffer(self.fbo.read(components=1, dtype="f1"), dtype=np.uint8)
            img = img.reshape(self.atlas, self.atlas)[::-1]  # rows top-down, like the camera image
            for i in idx:
                ax, ay = place[int(i)]
                tile = img[ay:ay + h[i], ax:ax + w[i]] > 0
                # The part of the tile that is inside the image (the canvas): image px = tile px + (x0, y0).
                c0, r0 = max(0, -int(x0[i])), max(0, -int(y0[i]))
                c1 = min(int(w[i]), cam.width - int(x0[i]))
                r1 = min(int(h[i]), cam.height - int(y0[i]))
                inside = tile[r0:r1, c0:c1] if c1 > c0 and r1 > r0 else tile[:0, :0]
                if self.weights is None:
                    total[slots[i]] = int(tile.sum())
                    in_image[slots[i]] = int(inside.sum())
                    continue
                lens, w_in, w_all = self.weights
                win = (slice(int(y0[i]) + r0, int(y0[i]) + r0 + inside.shape[0]),
                       slice(int(x0[i]) + c0, int(x0[i]) + c0 + inside.shape[1]))
                shown = float(w_in[win][inside].sum())
                beyond = tile.copy()
                beyond[r0:r0 + inside.shape[0], c0:c0 + inside.shape[1]] = False  # tile pixels off the canvas
                rows, cols = np.nonzero(beyond)
                off = float(lens.area_factor(*lens.normalised(cols + int(x0[i]), rows + int(y0[i]))).sum()) \
                    if len(rows) else 0.0
                in_image[slots[i]] = int(round(shown))
                total[slots[i]] = int(round(float(w_all[win][inside].sum()) + off))
            if len(rest) == len(todo):  # a single zebra larger than the atlas: count what fits
                break
            todo = rest

    def release(self) -> None:
        """Free the GL resources (and the context, if this counter made it)."""
        if self.owns_ctx:
            self.ctx.release()
