"""Draw motions: an animated 3D stick figure (GIF / MP4) or a PNG filmstrip of key frames.

Joints are (T, J, 3) positions with y up (HumanML3D / KIT convention). The camera and the axis
limits are fixed for the whole clip so the figure never jumps; limbs are coloured by side.
Drawing uses matplotlib's object API on an Agg canvas: no pyplot, no display, no global state.
"""

from __future__ import annotations

import os
import textwrap
from pathlib import Path
from typing import Iterator

import numpy as np
from PIL import Image
import matplotlib
from matplotlib.animation import FFMpegWriter
from matplotlib.artist import Artist
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d import Axes3D, proj3d
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from mlct.errors import MlctError
from mlct.io import atomic_path
from mlct.motion.motion_npy import check_finite, load_motion_npy, resolve_skeleton
from mlct.motion.skeleton import SKELETONS, Skeleton

FORMATS = (".gif", ".mp4", ".png")
MIN_FPS, MAX_FPS = 0.01, 1000.0  # what a GIF's delays and ffmpeg's frame rates can hold

# Animation frame: small enough that a 196-frame GIF renders in seconds on 2 cores.
FRAME_INCHES = 4.0
DPI = 90
# Filmstrip: one panel per key frame, side by side.
PANEL_INCHES = 2.2  # width of one panel
FILMSTRIP_FRAMES = 7
FILMSTRIP_DPI = 100

# A 3/4 front view: the standard processing faces the body +Z, so the camera sits on the +Z
# side, a little to the body's right and above the ground.
ELEVATION = 18.0
AZIMUTH = -60.0

COLORS = {
    "left": "#1f77b4",  # blue
    "right": "#e6550d",  # orange-red: told apart from blue also by colour-blind viewers
    "center": "#3a3a3a",  # spine and head
    "path": "#b5b5b5",  # the whole root trajectory
    "walked": "#6a3d9a",  # the part already travelled
    "ground": ("#e4e4e4", "#f4f4f4"),  # checker
}

# Lengths below are in metres and scaled by the skeleton's unit, so KIT (mm) gets the same view.
_UNIT_SCALE = {"m": 1.0, "mm": 1000.0}
_MARGIN = 0.25  # ground beyond the motion's footprint
_MIN_EXTENT = 1.2  # a standing figure still gets a floor around it
_CELL = 0.5  # checker cell
_MAX_CELLS = 24  # per side; long walks get bigger cells instead of thousands of polygons
_FILL = 0.94  # share of the frame the drawing fills


def render_motion(joints: np.ndarray, out: str | os.PathLike, skeleton: Skeleton | str,
                  title: str | None = None, fps: float | None = None) -> Path:
    """Draw (T, J, 3) joints (y up) to `out`: .gif / .mp4 animation or .png filmstrip."""
    out = Path(out)
    kind = _output_kind(out)
    skeleton = resolve_skeleton(skeleton)
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (skeleton.n_joints, 3) or len(joints) == 0:
        raise MlctError(f"joints of shape {joints.shape} do not fit the {skeleton.name} "
                        f"skeleton: expected (T >= 1, {skeleton.n_joints}, 3)")
    check_finite(joints, "joints")
    fps = skeleton.fps if fps is None else float(fps)
    if not np.isfinite(fps) or fps <= 0:
        raise MlctError(f"fps must be a positive number, got {fps}")
    if not MIN_FPS <= fps <= MAX_FPS:  # a GIF's frame delay is a 16-bit count of 1/100 s
        raise MlctError(f"fps {fps:g} is outside {MIN_FPS:g}..{MAX_FPS:g} frames per second")
    scene = _Scene(joints, skeleton)
    if kind == ".png":
        _render_filmstrip(scene, out, title, fps)
    else:
        _render_animation(scene, out, title, fps, kind)
    return out


def render_file(path: str | os.PathLike, out: str | os.PathLike,
                skeleton: Skeleton | str | None = None, caption: str | None = None,
                fps: float | None = None) -> Path:
    """Render a features (T, 263|251) or joints (T, J, 3) .npy file; see `render_motion`.

    The skeleton comes from the shape unless given; the caption is the title (`mlct render`
    takes it from the dataset's texts beside the file: mlct.data.layout.dataset_caption).
    """
    path, out = Path(path), Path(out)
    _output_kind(out)  # fail on a bad --out before loading anything
    if path.suffix.lower() == ".bvh":
        return _render_bvh(path, out, skeleton, caption, fps)
    if path.suffix.lower() not in (".npy", ""):
        raise MlctError(f"{path}: render reads .npy (features or joints) or .bvh files")
    joints, skel = load_motion_npy(path, skeleton)
    return render_motion(joints, out, skel, title=caption, fps=fps)


def _render_bvh(path: Path, out: Path, skeleton: Skeleton | str | None, caption: str | None,
                fps: float | None) -> Path:
    """A BVH whose joints carry a known skeleton's names (mlct's own BVH output does): drawn
    at the file's frame rate, in its units (mlct writes metres)."""
    from mlct.motion.bvh import read_bvh

    clip = read_bvh(path)
    candidates = [resolve_skeleton(skeleton)] if skeleton is not None else list(SKELETONS.values())
    for skel in candidates:
        if set(skel.joint_names) <= set(clip.joint_names):
            index = [clip.joint_names.index(name) for name in skel.joint_names]
            joints = clip.positions[:, index]
            return render_motion(joints, out, skel, title=caption,
                                 fps=clip.fps if fps is None else fps)
    names = ", ".join(s.name for s in candidates)
    raise MlctError(f"{path}: its joints are not those of a known skeleton ({names}); import it "
                    f"with `mlct data import --bvh DIR --joint-map MAP.json` and render the "
                    f"imported motion")


def limb_sides(skeleton: Skeleton) -> list[str]:
    """'left', 'right' or 'center' for each kinematic chain, decided from its joint names."""
    sides = []
    for chain in skeleton.kinematic_chain:
        # The chain's first joint is shared with its parent chain (pelvis, spine3, neck), so
        # only the joints the chain owns vote.
        names = [skeleton.joint_names[j].lower() for j in chain[1:]]
        left = sum("left" in n for n in names)
        right = sum("right" in n for n in names)
        sides.append("left" if left > right else "right" if right > left else "center")
    return sides


# --- checks -------------------------------------------------------------------------------------

def _output_kind(out: Path) -> str:
    """The output format from the extension; fails before any work is done."""
    kind = out.suffix.lower()
    if kind not in FORMATS:
        raise MlctError(f"cannot render to {out.name!r}: the extension must be one of "
                        f"{', '.join(FORMATS)}")
    if kind == ".mp4" and not _ffmpeg_available():
        raise MlctError(f"cannot write {out.name}: mp4 needs ffmpeg: pip install imageio-ffmpeg "
                        f"(or apt-get install ffmpeg), or write .gif")
    if out.is_dir():
        raise MlctError(f"cannot render to {out}: it is a directory")
    return kind


def _ffmpeg_available() -> bool:
    """matplotlib looks ffmpeg up on PATH (or rcParams['animation.ffmpeg_path']); without one
    there, the binary the imageio-ffmpeg wheel ships (a dependency) is used."""
    if FFMpegWriter.isAvailable():
        return True
    try:
        import imageio_ffmpeg

        path = imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return False
    matplotlib.rcParams["animation.ffmpeg_path"] = path
    return FFMpegWriter.isAvailable()


# --- drawing ------------------------------------------------------------------------------------

class _Scene:
    """What every view of one motion shares: the data, fixed limits, ground and trajectory."""

    def __init__(self, joints: np.ndarray, skeleton: Skeleton) -> None:
        if skeleton.unit not in _UNIT_SCALE:
            raise MlctError(f"skeleton {skeleton.name!r} has unknown unit {skeleton.unit!r}")
        scale = _UNIT_SCALE[skeleton.unit]
        self.joints = joints  # (T, J, 3)
        self.skeleton = skeleton
        self.sides = limb_sides(skeleton)
        root = skeleton.parents.index(-1)
        self.head = skeleton.joint_names.index("head") if "head" in skeleton.joint_names else None
        lo, hi = joints.min(axis=(0, 1)), joints.max(axis=(0, 1))
        # The floor is y = 0 (the standard processing puts the feet there), or lower if the data
        # goes below it, so the figure never stands inside the ground.
        self.floor = min(0.0, float(lo[1]))
        limits = []
        for axis in (0, 2):  # x, z: the footprint plus a margin, at least _MIN_EXTENT wide
            a, b = lo[axis] - _MARGIN * scale, hi[axis] + _MARGIN * scale
            pad = max(0.0, _MIN_EXTENT * scale - (b - a)) / 2
            limits.append((float(a - pad), float(b + pad)))
        top = max(float(hi[1]), self.floor + 1.0 * scale) + 0.1 * scale
        self.xlim, self.zlim = limits
        self.ylim = (self.floor, top)
        # Equal scale on all axes: the box is as long as the data on each axis.
        self.box = tuple(b - a for a, b in (self.xlim, self.ylim, self.zlim))
        self.path = joints[:, root, [0, 2]]  # (T, 2) root on the ground
        self.cell = max(_CELL * scale, self.box[0] / _MAX_CELLS, self.box[2] / _MAX_CELLS)
        # Filmstrip panels follow the root inside a window that holds every pose around it.
        reach = np.abs(joints[:, :, [0, 2]] - self.path[:, None, :]).max()
        self.half_window = max(float(reach) + _MARGIN * scale, _MIN_EXTENT * scale / 2)

    def window(self, frame: int) -> tuple[tuple[float, float], tuple[float, float]]:
        """x and z limits of the square window centred on the root at `frame`."""
        x, z = self.path[frame]
        h = self.half_window
        return (float(x - h), float(x + h)), (float(z - h), float(z + h))

    def checker(self, xlim: tuple[float, float],
                zlim: tuple[float, float]) -> list[list[np.ndarray]]:
        """Ground quads on y = floor covering the limits, split in the two checker colours."""
        (x0, x1), (z0, z1) = xlim, zlim
        cell = self.cell
        # Cells on a world grid, so the checker stays put while a root-following window moves.
        xs = np.arange(np.floor(x0 / cell), np.ceil(x1 / cell)) * cell
        zs = np.arange(np.floor(z0 / cell), np.ceil(z1 / cell)) * cell
        cells: list[list[np.ndarray]] = [[], []]
        for x in xs:
            for z in zs:
                # Clip to the limits so the floor is a clean rectangle under the motion.
                a, b = max(x, x0), min(x + cell, x1)
                c, d = max(z, z0), min(z + cell, z1)
                quad = np.array([[a, self.floor, c], [b, self.floor, c], [b, self.floor, d],
                                 [a, self.floor, d]])
                parity = int(round(x / cell) + round(z / cell)) % 2
                cells[parity].append(quad)
        return cells


class _StickFigure:
    """The artists of one 3D axes; `update` moves them to a frame without redrawing the axes."""

    def __init__(self, ax: Axes3D, scene: _Scene, xlim: tuple[float, float],
                 zlim: tuple[float, float], linewidth: float = 2.5) -> None:
        self.ax, self.scene = ax, scene
        # Fixed camera, y drawn vertical, equal scale on all axes. Depth sorting is off: the
        # camera is above the floor, so the floor is always at the back and the body in front.
        ax.view_init(elev=ELEVATION, azim=AZIMUTH, vertical_axis="y")
        ax.set_xlim(*xlim)
        ax.set_ylim(*scene.ylim)
        ax.set_zlim(*zlim)
        # Kept: mplot3d stores the aspect rolled to its vertical axis, so it can't be read back.
        self.aspect = (xlim[1] - xlim[0], scene.ylim[1] - scene.ylim[0], zlim[1] - zlim[0])
        ax.set_box_aspect(self.aspect)
        ax.set_axis_off()  # ticks and panes cost time and add nothing the checker lacks
        ax.computed_zorder = False
        for cells, color in zip(scene.checker(xlim, zlim), COLORS["ground"]):
            ax.add_collection3d(Poly3DCollection(cells, facecolors=color, edgecolors="none",
                                                 zorder=0))
        self.corners = np.array([[x, scene.floor, z] for x in xlim for z in zlim])  # (4, 3)
        path = scene.path
        inside = ((path[:, 0] >= xlim[0]) & (path[:, 0] <= xlim[1])
                  & (path[:, 1] >= zlim[0]) & (path[:, 1] <= zlim[1]))
        path = np.where(inside[:, None], path, np.nan)  # mplot3d does not clip to the limits
        self.path = path
        floor = np.full(len(path), scene.floor)
        ax.plot(path[:, 0], floor, path[:, 1], color=COLORS["path"], lw=1.2, zorder=1)
        (self.walked,) = ax.plot([], [], [], color=COLORS["walked"], lw=1.6, zorder=2)
        self.moving: list[Artist] = [self.walked]  # what `update` changes, in drawing order
        self.limbs = []
        for chain, side in zip(scene.skeleton.kinematic_chain, scene.sides):
            # Limbs above the spine so the arms stay visible in front of the torso.
            (line,) = ax.plot([], [], [], color=COLORS[side], lw=linewidth, marker="o",
                              markersize=linewidth * 0.9, solid_capstyle="round",
                              zorder=4 if side != "center" else 3)
            self.limbs.append((np.array(chain), line))
        self.head = None
        if scene.head is not None:
            (self.head,) = ax.plot([], [], [], color=COLORS["center"], marker="o",
                                   markersize=linewidth * 3.2, linestyle="none", zorder=3)
            self.moving.append(self.head)
        self.moving += [line for _, line in self.limbs]
        self.moving.sort(key=lambda artist: artist.get_zorder())

    def update(self, frame: int) -> None:
        pose = self.scene.joints[frame]  # (J, 3)
        for chain, line in self.limbs:
            line.set_data_3d(pose[chain, 0], pose[chain, 1], pose[chain, 2])
        if self.head is not None:
            head = pose[self.scene.head]
            self.head.set_data_3d([head[0]], [head[1]], [head[2]])
        walked = self.path[: frame + 1]
        self.walked.set_data_3d(walked[:, 0], np.full(len(walked), self.scene.floor),
                                walked[:, 1])


def _project(ax: Axes3D, points: np.ndarray) -> np.ndarray:
    """(N, 3) data points -> (N, 2) pixels relative to the axes' centre, under its camera."""
    x, y, _ = proj3d.proj_transform(points[:, 0], points[:, 1], points[:, 2], ax.get_proj())
    px = ax.transData.transform(np.column_stack([x, y]))
    bbox = ax.bbox
    return px - np.array([bbox.x0 + bbox.width / 2, bbox.y0 + bbox.height / 2])


def _fit_zoom(ax: Axes3D, aspect: tuple[float, float, float], points: np.ndarray) -> float:
    """The zoom at which `points` fill the (square) axes, `_FILL` of its width or height.

    mplot3d fits the whole limits box in the axes whatever the camera, which leaves most of a
    frame empty at a low elevation; zooming to what is actually drawn uses the frame.
    """
    zoom = 1.0
    for _ in range(3):  # perspective makes the zoom slightly non-linear: refine
        ax.set_box_aspect(aspect, zoom=zoom)
        px = _project(ax, points)
        size = np.maximum(px.max(axis=0) - px.min(axis=0), 1e-9)
        zoom *= _FILL * min(ax.bbox.width / size[0], ax.bbox.height / size[1])
    return zoom


def _wrap_title(title: str, width_inches: float, fontsize: float) -> str:
    """Wrap a caption to the figure width; at most 3 lines, the rest elided."""
    chars = max(20, int(width_inches * 72 / (fontsize * 0.55)))
    lines = textwrap.wrap(" ".join(title.split()), width=chars)
    if len(lines) > 3:
        lines = lines[:3]
        lines[-1] = textwrap.shorten(lines[-1] + " …", width=chars, placeholder=" …")
    return "\n".join(lines)


def _figure(width: float, n_panels: int) -> tuple[Figure, list[Axes3D]]:
    """A white Agg figure with `n_panels` square 3D axes side by side (placed by `_layout`)."""
    fig = Figure(figsize=(width, width / n_panels), facecolor="white")
    FigureCanvasAgg(fig)
    axes = [fig.add_axes((i / n_panels, 0, 1 / n_panels, 1), projection="3d")
            for i in range(n_panels)]
    return fig, axes


def _layout(fig: Figure, panels: list[tuple[Axes3D, _StickFigure, np.ndarray]],
            title: str | None, fontsize: float, label_inches: float = 0.0) -> None:
    """Zoom the panels onto what they draw and size the figure to it, title on top.

    All panels get one zoom and one placement, so a body keeps its size and the floors line up
    from panel to panel. Each axes stays square (mplot3d draws in a square) and may reach past
    the figure's edge where it has nothing to draw; the figure is only as tall as the content,
    so a long walk does not leave the top half of every frame empty.
    """
    width = fig.get_figwidth()
    panel = width / len(panels)  # inches; each axes is panel x panel
    zoom = min(_fit_zoom(ax, figure.aspect, points) for ax, figure, points in panels)
    extents = []
    for ax, figure, points in panels:
        ax.set_box_aspect(figure.aspect, zoom=zoom)
        extents.append(_project(ax, points))
    extents_in = np.concatenate(extents) / fig.dpi
    lo, hi = extents_in.min(axis=0), extents_in.max(axis=0)
    content = min(panel, max(0.5 * panel, (hi[1] - lo[1]) / _FILL))
    text = _wrap_title(title, width, fontsize) if title else ""
    title_h = (text.count("\n") + 1) * fontsize * 1.35 / 72 + 0.12 if text else 0.0
    height = label_inches + content + title_h
    fig.set_size_inches(width, height)
    centre_y = label_inches + content / 2
    for i, (ax, _, _) in enumerate(panels):
        # Put the content's centre (offset (lo + hi) / 2 from the axes' centre) mid-panel.
        cx = (i + 0.5) * panel - (lo[0] + hi[0]) / 2
        cy = centre_y - (lo[1] + hi[1]) / 2
        ax.set_position(((cx - panel / 2) / width, (cy - panel / 2) / height, panel / width,
                         panel / height))
    if text:
        fig.suptitle(text, fontsize=fontsize, y=1 - 0.06 / height, va="top")
    _side_legend(fig, width, height, fontsize * 0.8)


def _side_legend(fig: Figure, width: float, height: float, fontsize: float) -> None:
    """'left' and 'right' in their limbs' colours, bottom right: which arm is which."""
    char = 0.6 * fontsize / 72  # inches per character, roughly
    x = 1 - 0.06 / width
    for side in ("right", "left"):
        fig.text(x, 0.04 / height, side, color=COLORS[side], fontsize=fontsize, ha="right",
                 va="bottom", fontweight="bold")
        x -= (len(side) + 1.5) * char / width


def _sample(joints: np.ndarray, n: int = 64) -> np.ndarray:
    """(<= n * J, 3) joints of n evenly spaced frames: enough to bound the motion's projection."""
    frames = np.unique(np.linspace(0, len(joints) - 1, min(n, len(joints))).round().astype(int))
    return joints[frames].reshape(-1, 3)


def _render_animation(scene: _Scene, out: Path, title: str | None, fps: float,
                      kind: str) -> None:
    fig, (ax,) = _figure(FRAME_INCHES, 1)
    figure = _StickFigure(ax, scene, scene.xlim, scene.zlim)
    # One camera for the whole clip, framed on everything the clip ever draws.
    _layout(fig, [(ax, figure, np.concatenate([figure.corners, _sample(scene.joints)]))],
            title, fontsize=10)
    n_frames = len(scene.joints)
    with atomic_path(out) as tmp:
        if kind == ".gif":
            _write_gif(tmp, *_blit_frames(fig, figure, n_frames), n_frames, fps)
        else:
            # ffmpeg takes whole figures: matplotlib redraws each one, slower but still fine.
            writer = FFMpegWriter(fps=fps)
            with writer.saving(fig, str(tmp), dpi=DPI):
                for frame in range(n_frames):
                    figure.update(frame)
                    writer.grab_frame()


def _blit_frames(fig: Figure, figure: _StickFigure,
                 n_frames: int) -> tuple[np.ndarray, Iterator[np.ndarray]]:
    """The static scene (floor, path, title) drawn once, then each frame: the moving artists
    drawn on a copy of it. Images are (H, W) uint32, one RGBA pixel per number."""
    fig.set_dpi(DPI)
    canvas = fig.canvas
    assert isinstance(canvas, FigureCanvasAgg)
    for artist in figure.moving:
        artist.set_animated(True)  # left out of full draws, so that one draws the scene only
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)

    def pixels() -> np.ndarray:
        return np.asarray(canvas.buffer_rgba()).view(np.uint32)[..., 0].copy()

    def frames() -> Iterator[np.ndarray]:
        for frame in range(n_frames):
            figure.update(frame)
            canvas.restore_region(background)
            for artist in figure.moving:
                figure.ax.draw_artist(artist)  # with the camera of the full draw (ax.M)
            yield pixels()

    return pixels(), frames()


def _write_gif(path: Path, scene: np.ndarray, frames: Iterator[np.ndarray], n_frames: int,
               fps: float) -> None:
    """An animated GIF of (H, W) uint32 RGBA frames, with one exact palette for all of them.

    Pillow would quantize every frame on its own (median cut), which costs more than drawing
    it, and its palette lookup rounds colours (white comes out light grey). The scene has few
    colours, all of them in the static scene and the first, middle and last frames (the last
    one has the whole travelled path): their 256 most frequent colours are the palette. Only
    the pixels where a frame differs from the scene need looking up.
    """
    images = list(frames)
    picks = [scene] + [images[i] for i in sorted({0, n_frames // 2, n_frames - 1})]
    colours, counts = np.unique(np.concatenate(picks), return_counts=True)
    palette = _Palette(colours[np.argsort(-counts, kind="stable")[:256]])
    scene_index = palette.index(scene)
    indexed = []
    for image in images:
        index = scene_index.copy()
        moved = image != scene
        index[moved] = palette.index(image[moved])
        gif_frame = Image.fromarray(index, mode="P")
        gif_frame.putpalette(palette.rgb_bytes)
        indexed.append(gif_frame)
    # GIF delays are in 1/100 s: 20 fps -> 50 ms, 12.5 fps -> 80 ms are exact.
    indexed[0].save(path, format="GIF", save_all=True, append_images=indexed[1:],
                    duration=max(10, round(1000 / fps)), loop=0)


def _rgb(pixels: np.ndarray) -> np.ndarray:
    """(...) uint32 RGBA pixels (R in the low byte) -> (..., 3) int64 RGB."""
    pixels = pixels.astype(np.int64)
    return np.stack([pixels & 255, (pixels >> 8) & 255, (pixels >> 16) & 255], axis=-1)


class _Palette:
    """Up to 256 colours, and a growing memo of which entry every colour seen maps to."""

    def __init__(self, colours: np.ndarray) -> None:
        self.colours = colours  # (N,) uint32 RGBA
        self.rgb_bytes = _rgb(colours).astype(np.uint8).tobytes()
        order = np.argsort(colours)
        self.known, self.known_index = colours[order], order.astype(np.uint8)

    def index(self, pixels: np.ndarray) -> np.ndarray:
        """uint8 palette index of each pixel's colour: its own entry, else the nearest one."""
        shades, inverse = np.unique(pixels, return_inverse=True)
        slot = np.minimum(np.searchsorted(self.known, shades), len(self.known) - 1)
        new = self.known[slot] != shades
        if new.any():
            # Anti-aliasing shades not met before: nearest entry, remembered for later frames.
            fresh = shades[new]
            distance = ((_rgb(fresh)[:, None, :] - _rgb(self.colours)[None]) ** 2).sum(-1)
            known = np.concatenate([self.known, fresh])
            order = np.argsort(known, kind="stable")
            self.known = known[order]
            self.known_index = np.concatenate(
                [self.known_index, distance.argmin(axis=1).astype(np.uint8)])[order]
            slot = np.searchsorted(self.known, shades)
        return self.known_index[slot][inverse.reshape(pixels.shape)]


def _render_filmstrip(scene: _Scene, out: Path, title: str | None, fps: float) -> None:
    n_frames = len(scene.joints)
    frames = np.unique(np.linspace(0, n_frames - 1, min(n_frames, FILMSTRIP_FRAMES)).round())
    frames = frames.astype(int)
    fig, axes = _figure(PANEL_INCHES * len(frames), len(frames))
    panels = []
    for ax, frame in zip(axes, frames):
        # Each panel follows the root, so the body stays large however far the motion goes;
        # the floor's checker is fixed to the world, so the travel still shows.
        figure = _StickFigure(ax, scene, *scene.window(frame), linewidth=2.0)
        figure.update(frame)
        panels.append((ax, figure, np.concatenate([figure.corners, scene.joints[frame]])))
    label = 0.25  # inches under the panels for the time stamps
    _layout(fig, panels, title, fontsize=12, label_inches=label)
    for i, frame in enumerate(frames):
        fig.text((i + 0.5) / len(frames), 0.04 / fig.get_figheight(), f"{frame / fps:.1f} s",
                 ha="center", va="bottom", fontsize=9, color="#555555")
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=FILMSTRIP_DPI, format="png", facecolor="white")
