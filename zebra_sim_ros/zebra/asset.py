"""Baking the zebra: every clip frame's posed vertices, joints, keypoints and box, in a fast cache.

The cache is a folder of ``.npy`` arrays (memory-mapped on load) keyed by the asset version and a
digest of the code that shapes the zebra, so editing a clip or a proportion rebuilds it and nothing
stale is ever served. Frames are numbered globally: clip ``c`` owns frames
``clip_start[c] .. clip_start[c] + clip_frames[c] - 1``.

Per frame and morph the cache holds posed vertices for both levels of detail, the joints' posed
transforms, the keypoints and the posed mesh's box in the asset frame (x forward, y left, z up,
origin on the ground). That box is aligned with the animal's body frame; placed in the world with
the zebra's yaw, tilt and scale it is the oriented bounding box the placer and labeller use.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import stat
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from zebra_sim_ros.errors import AssetError, ParameterError
from zebra_sim_ros.geometry.rotations import euler_zyx, rigid, rot_y
from zebra_sim_ros.zebra import animation, coat, keypoints, mesh, skeleton, skinning
from zebra_sim_ros.zebra.animation import CLIPS
from zebra_sim_ros.zebra.keypoints import keypoint_weights, pose_keypoints
from zebra_sim_ros.zebra.mesh import LODS, ZebraMesh, build_mesh
from zebra_sim_ros.zebra.skeleton import MORPHS, bind_positions, forward_kinematics
from zebra_sim_ros.zebra.skinning import skin, skinning_matrices

FloatArray = NDArray[np.float64]
ASSET_VERSION = 1
_SOURCES = (skeleton, mesh, animation, keypoints, skinning)


def asset_digest() -> str:
    """Digest of the asset version and the source of every module that shapes the zebra."""
    h = hashlib.sha256(f"v{ASSET_VERSION}".encode())
    for mod in _SOURCES:
        h.update(Path(str(mod.__file__)).read_bytes())
    return h.hexdigest()[:16]


def appearance_digest() -> str:
    """Digest of what an animal looks like in a render: the asset (:func:`asset_digest`) and the coats' source. Sets
    rendered with another appearance (the other species' hides, say) must not be reused as if they were today's;
    the asset cache itself does not hold coats and keys on :func:`asset_digest` alone."""
    h = hashlib.sha256(asset_digest().encode())
    h.update(Path(str(coat.__file__)).read_bytes())
    return h.hexdigest()[:16]


def default_cache_root() -> Path:
    """``$ZEBRA_SIM_CACHE`` if set, else ``$XDG_CACHE_HOME/zebra_sim_ros`` (``~/.cache/zebra_sim_ros``)."""
    env = os.environ.get("ZEBRA_SIM_CACHE")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "zebra_sim_ros"


def library_dir(cache_root: Path | None = None) -> Path:
    """This code version's zebra cache: ``<cache root>/zebra-<asset digest>``."""
    return (cache_root or default_cache_root()) / f"zebra-{asset_digest()}"


def coat_store_dir(cache_root: Path | None = None) -> Path:
    """This code version's coat store (:class:`~zebra_sim_ros.zebra.coat_store.CoatStore`):
    ``<cache root>/coats-<appearance digest>-np<numpy version>``."""
    return (cache_root or default_cache_root()) / f"coats-{appearance_digest()}-np{np.__version__}"


# The cache root's folders that are ours: zebra caches, their builds in progress (``.tmp<pid>``) and coat stores
# (named without the numpy version before it was part of the key). Nothing else under the root is ever touched.
_OUR_FOLDER = re.compile(r"zebra-[0-9a-f]{16}(\.tmp(?P<pid>[0-9]+))?|coats-[0-9a-f]{16}(-np[0-9A-Za-z.+_-]+)?")
BUILD_QUIET_S = 3600.0  # a build folder untouched this long, whose process is not running here, was interrupted


@dataclass(frozen=True)
class CacheFolder:
    """One of the cache root's folders: a zebra cache, a build of one, or a coat store."""

    path: Path
    current: bool  # read by this code version and numpy build (its zebra cache or coat store)
    building: bool  # a build whose process runs here, or one touched within BUILD_QUIET_S (another machine's?)
    bytes: int  # size of its files


@dataclass(frozen=True)
class PruneResult:
    """What :func:`prune_cache` removed (on a dry run: would remove), could not remove, and left."""

    removed: list[CacheFolder]
    failed: list[CacheFolder]  # removed in part or not at all (permissions, a folder in use elsewhere)
    kept: list[CacheFolder]


def cache_folders(cache_root: Path | None = None) -> list[CacheFolder]:
    """The zebra caches, builds and coat stores under the cache root, by name; none if the root is not there."""
    root = cache_root or default_cache_root()
    if not root.is_dir():
        return []
    current = {library_dir(root).name, coat_store_dir(root).name}
    out = []
    for path in sorted(root.iterdir()):
        m = _OUR_FOLDER.fullmatch(path.name)
        if m is None or path.is_symlink() or not path.is_dir():
            continue
        building = m["pid"] is not None and (_alive(int(m["pid"])) or _quiet_s(path) < BUILD_QUIET_S)
        out.append(CacheFolder(path, path.name in current, building, _folder_bytes(path)))
    return out


def prune_cache(cache_root: Path | None = None, everything: bool = False, dry_run: bool = False) -> PruneResult:
    """Remove the cache root's folders that this code version does not read: zebra caches and coat stores of other
    code or another numpy build (each edit of the zebra or its coats starts new ones, and nothing else removes the
    old), and interrupted builds. ``everything``: this version's too (the cache is rebuilt on next use; the USD files
    ``asset build`` wrote into it are not). A build is left while its process runs on this machine or while it was
    touched within :data:`BUILD_QUIET_S`, and nothing under the root that is not named as ours is touched. Processes
    using a removed folder (other versions of this tool; with ``everything``, this one's) lose their cache: prune when
    they are not running."""
    found = cache_folders(cache_root)
    chosen = [f for f in found if not f.building and (everything or not f.current)]
    if dry_run:
        return PruneResult(chosen, [], [f for f in found if f not in chosen])
    for f in chosen:
        shutil.rmtree(f.path, ignore_errors=True)
    failed = [f for f in chosen if f.path.exists()]
    return PruneResult([f for f in chosen if f not in failed], failed, [f for f in found if f not in chosen])


def _folder_bytes(path: Path) -> int:
    """Bytes of the files under ``path``, links not followed; files and folders that vanish meanwhile (a camera's
    claims, another prune) count as nothing."""
    total = 0
    for top, _, files in os.walk(path):
        for name in files:
            try:
                st = os.lstat(os.path.join(top, name))
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode):
                total += st.st_size
    return total


def _quiet_s(path: Path) -> float:
    """Seconds since anything directly in ``path`` changed (infinite if it is gone)."""
    try:
        latest = max([path.stat().st_mtime, *(p.lstat().st_mtime for p in path.iterdir())])
    except OSError:
        return float("inf")
    return time.time() - latest


def _alive(pid: int) -> bool:
    """Whether process ``pid`` is running on this machine."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's
        return True
    except OverflowError:  # not a pid this system can have
        return False
    return True


@dataclass(frozen=True)
class PosedZebras:
    """N placed zebras in one frame, in the world (or any parent) frame.

    Attributes:
        vertices: (N, V, 3) float32 posed, scaled, placed mesh vertices (the LOD asked for).
        joints: (N, J, 3) joint positions.
        keypoints: (N, K, 3) keypoint positions.
        box_center: (N, 3), box_rotation: (N, 3, 3) (columns: the zebra's forward, left, up axes),
        box_extent: (N, 3) full side lengths, metres: the oriented box of the posed mesh.
    """

    vertices: NDArray[np.float32]
    joints: FloatArray
    keypoints: FloatArray
    box_center: FloatArray
    box_rotation: FloatArray
    box_extent: FloatArray

    def box_corners(self) -> FloatArray:
        """(N, 8, 3) corners of the oriented boxes; corner bit i set = +half extent on axis i."""
        signs = np.array([[(c >> i & 1) * 2 - 1 for i in range(3)] for c in range(8)], dtype=np.float64)
        half = self.box_extent[:, None, :] * 0.5 * signs[None]
        return self.box_center[:, None, :] + np.einsum("nij,ncj->nci", self.box_rotation, half)


class ZebraLibrary:
    """The baked zebra: topology per level of detail and per-frame data for every morph.

    Build one with :func:`build_library`, open one with :func:`load_library`.
    """

    def __init__(self, root: Path, arrays: dict[str, NDArray[np.generic]], manifest: dict[str, object]):
        self.root = root
        self.manifest = manifest
        self.morphs: tuple[str, ...] = tuple(manifest["morphs"])  # type: ignore[arg-type]
        self.clip_names: tuple[str, ...] = tuple(manifest["clips"])  # type: ignore[arg-type]
        self.clip_frames = np.asarray(manifest["clip_frames"], dtype=np.int64)
        self.clip_loop = np.asarray(manifest["clip_loop"], dtype=bool)
        self.clip_start = np.concatenate([[0], np.cumsum(self.clip_frames)[:-1]]).astype(np.int64)
        self.n_frames = int(self.clip_frames.sum())
        self._a = arrays

    # -- static data -------------------------------------------------------------------------
    def faces(self, lod: int = 0) -> NDArray[np.int64]:
        """(F, 3) triangles of level of detail ``lod`` (the same for every morph)."""
        return np.asarray(self._a[f"faces_lod{lod}"])

    def uv(self, lod: int = 0) -> NDArray[np.float32]:
        """(F, 3, 2) face-varying UVs of level of detail ``lod``."""
        return np.asarray(self._a[f"uv_lod{lod}"])

    def face_part(self, lod: int = 0) -> NDArray[np.int8]:
        """(F,) part index of each triangle (see ``mesh.PART_NAMES``)."""
        return np.asarray(self._a[f"face_part_lod{lod}"])

    def bind_vertices(self, morph: int, lod: int = 0) -> NDArray[np.float32]:
        """(V, 3) bind-pose vertices."""
        return np.asarray(self._a[f"bind_lod{lod}"][morph])

    # -- per-frame data ----------------------------------------------------------------------
    def frame_index(self, clip: str | int, frame: int) -> int:
        """Global frame index of ``frame`` in ``clip`` (a name or an index)."""
        c = self.clip_names.index(clip) if isinstance(clip, str) else int(clip)
        if not 0 <= frame < self.clip_frames[c]:
            raise ParameterError("frame", frame, f"0..{self.clip_frames[c] - 1} for clip {self.clip_names[c]}")
        return int(self.clip_start[c] + frame)

    def vertices(self, morph: int, frame: int | NDArray[np.int64], lod: int = 0) -> NDArray[np.float32]:
        """Posed vertices in the asset frame: (V, 3), or (N, V, 3) for an array of frames."""
        return np.asarray(self._a[f"vertices_lod{lod}"][morph, frame])

    def joint_transforms(self, morph: int, frame: int | NDArray[np.int64]) -> NDArray[np.float32]:
        """(J, 4, 4) posed joint-to-asset transforms, or (N, J, 4, 4) for an array of frames."""
        return np.asarray(self._a["joints"][morph, frame])

    def keypoints(self, morph: int, frame: int) -> NDArray[np.float32]:
        """(K, 3) keypoints in the asset frame."""
        return np.asarray(self._a["keypoints"][morph, frame])

    def boxes(self) -> NDArray[np.float32]:
        """(M, N_frames, 2, 3) min and max corner of each posed mesh in the asset frame."""
        return np.asarray(self._a["boxes"])

    def pose(self, morph: NDArray[np.int64], frame: NDArray[np.int64], scale: FloatArray,
             rotation: FloatArray, translation: FloatArray, lod: int = 0) -> PosedZebras:
        """Place N zebras: ``p_world = rotation @ (scale * p_asset) + translation``.

        Args:
            morph, frame: (N,) morph indices and global frame indices.
            scale: (N,) uniform scale; rotation: (N, 3, 3); translation: (N, 3) metres.
            lod: level of detail of the returned vertices.
        """
        morph = np.asarray(morph, dtype=np.int64)
        frame = np.asarray(frame, dtype=np.int64)
        scale = np.asarray(scale, dtype=np.float64)
        rotation = np.asarray(rotation, dtype=np.float64)
        translation = np.asarray(translation, dtype=np.float64)
        sr = (rotation * scale[:, None, None]).astype(np.float32)
        t32 = translation.astype(np.float32)
        verts = self._a[f"vertices_lod{lod}"][morph, frame]  # (N, V, 3) gathered from the memmap
        out = np.matmul(verts, sr.transpose(0, 2, 1)) + t32[:, None, :]
        sr64 = rotation * scale[:, None, None]
        joint_pos = np.asarray(self._a["joints"][morph, frame, :, :3, 3], dtype=np.float64)
        kp_local = np.asarray(self._a["keypoints"][morph, frame], dtype=np.float64)
        joints = np.einsum("nij,nkj->nki", sr64, joint_pos) + translation[:, None]
        kps = np.einsum("nij,nkj->nki", sr64, kp_local) + translation[:, None]
        box = self._a["boxes"][morph, frame].astype(np.float64)  # (N, 2, 3)
        centre_local = box.mean(axis=1)
        centre = np.einsum("nij,nj->ni", sr64, centre_local) + translation
        extent = (box[:, 1] - box[:, 0]) * scale[:, None]
        return PosedZebras(out, joints, kps, centre, rotation.copy(), extent)


def _bake_morph(morph_name: str, meshes: dict[int, ZebraMesh]) -> dict[str, NDArray[np.generic]]:
    m = MORPHS[morph_name]
    bind = bind_positions(m)
    kp_idx, kp_w = keypoint_weights(meshes[0])
    out: dict[str, list[NDArray[np.generic]]] = {"joints": [], "keypoints": [], "boxes": []}
    for lod in meshes:
        out[f"vertices_lod{lod}"] = []
    for clip in CLIPS:
        poses = [clip.pose(f) for f in range(clip.frames)]
        ang = np.radians(np.stack([p.angles for p in poses]))  # (F, J, 3) yaw, pitch, roll
        local = euler_zyx(ang[..., 0], ang[..., 1], ang[..., 2])
        root = rigid(rot_y(np.radians([p.root_pitch for p in poses])), np.zeros((len(poses), 3)))
        g = forward_kinematics(bind, local, root)
        mats = skinning_matrices(g, bind)
        verts = {lod: skin(meshes[lod].vertices, meshes[lod].joint_indices, meshes[lod].joint_weights, mats)
                 for lod in meshes}
        # Ground contact: the lowest point of the full-detail mesh rests on z = 0 (plus any lift).
        dz = -verts[0][..., 2].min(axis=1) + np.array([p.lift for p in poses])
        for lod in meshes:
            verts[lod][..., 2] += dz[:, None]
            out[f"vertices_lod{lod}"].append(verts[lod].astype(np.float32))
        g[..., 2, 3] += dz[:, None]
        out["joints"].append(g.astype(np.float32))
        out["keypoints"].append(pose_keypoints(verts[0], kp_idx, kp_w).astype(np.float32))
        out["boxes"].append(np.stack([verts[0].min(axis=1), verts[0].max(axis=1)], axis=1).astype(np.float32))
    return {k: np.concatenate(v) for k, v in out.items()}


def build_library(cache_root: Path | None = None, force: bool = False) -> ZebraLibrary:
    """Bake every morph, clip and frame into the cache (skipped if an intact one exists)."""
    root = library_dir(cache_root)
    if not force and (root / "manifest.json").exists():
        return load_library(cache_root)
    t0 = time.perf_counter()
    tmp = root.with_name(root.name + f".tmp{os.getpid()}")
    tmp.mkdir(parents=True, exist_ok=True)
    morph_names = tuple(MORPHS)
    per_morph = []
    static: dict[str, NDArray[np.generic]] = {}
    for name in morph_names:
        meshes = {lod: build_mesh(MORPHS[name], lod) for lod in LODS}
        per_morph.append(_bake_morph(name, meshes))
        for lod, msh in meshes.items():
            static[f"faces_lod{lod}"] = msh.faces
            static[f"uv_lod{lod}"] = msh.uv
            static[f"face_part_lod{lod}"] = msh.face_part
            static.setdefault(f"bind_lod{lod}", [])  # type: ignore[arg-type]
            static[f"bind_lod{lod}"].append(msh.vertices.astype(np.float32))  # type: ignore[attr-defined]
    for key in per_morph[0]:
        np.save(tmp / f"{key}.npy", np.stack([p[key] for p in per_morph]))
    for key, val in static.items():
        np.save(tmp / f"{key}.npy", np.asarray(val))
    manifest = {
        "asset_version": ASSET_VERSION,
        "digest": asset_digest(),
        "morphs": list(morph_names),
        "clips": [c.name for c in CLIPS],
        "clip_frames": [c.frames for c in CLIPS],
        "clip_loop": [c.loop for c in CLIPS],
        "fps": animation.FPS,
        "keypoints": list(keypoints.KEYPOINT_NAMES),
        "keypoint_edges": [list(e) for e in keypoints.KEYPOINT_EDGES],
        "joints": list(skeleton.JOINT_NAMES),
        "lods": list(LODS),
        "build_seconds": round(time.perf_counter() - t0, 3),
    }
    (tmp / "manifest.json").write_text(json.dumps(manifest, indent=1))
    if not force and (root / "manifest.json").exists():  # another process finished the same build first
        shutil.rmtree(tmp)
        return load_library(cache_root)
    if root.exists():  # a forced build, or a broken cache without its manifest: replace it whole
        shutil.rmtree(root)
    try:
        tmp.rename(root)
    except OSError:  # a concurrent build renamed its copy in between: theirs is as good
        shutil.rmtree(tmp, ignore_errors=True)
    return load_library(cache_root)


def load_library(cache_root: Path | None = None, build_if_missing: bool = True) -> ZebraLibrary:
    """Open the baked zebra for this code version, building it first if it is missing."""
    root = library_dir(cache_root)
    manifest_path = root / "manifest.json"
    if not manifest_path.exists():
        if build_if_missing:
            return build_library(cache_root)
        raise AssetError(f"no zebra cache at {root}: run 'zebra-sim asset build'")
    try:
        manifest = json.loads(manifest_path.read_text())
        arrays = {p.stem: np.load(p, mmap_mode="r") for p in root.glob("*.npy")}
    except (OSError, ValueError) as exc:
        raise AssetError(f"zebra cache at {root} is unreadable ({exc}); delete it and rebuild") from exc
    needed = {"joints", "keypoints", "boxes"} | {f"vertices_lod{lod}" for lod in LODS}
    missing = needed - set(arrays)
    if missing:
        raise AssetError(f"zebra cache at {root} lacks {sorted(missing)}; delete it and rebuild")
    return ZebraLibrary(root, arrays, manifest)
