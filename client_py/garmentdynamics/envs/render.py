"""A small software renderer for the Gymnasium environments' render_mode "rgb_array": the garment's
triangles drawn over the table from a fixed oblique camera, flat-shaded, nearest triangle on top
(painter's algorithm). NumPy only; no display or GPU needed."""

import numpy as np

TABLE_RGB = np.array([205, 190, 160], dtype=np.float64)  # the table, a light wood
CLOTH_RGB = np.array([70, 110, 180], dtype=np.float64)   # the garment, blue
BACKGROUND_RGB = np.array([235, 238, 242], dtype=np.uint8)


def _camera(elevation_deg: float, azimuth_deg: float):
    """Rows: the camera's right, up and viewing (into the scene) axes, world frame."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    view = -np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])  # towards the scene
    right = np.cross(view, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, view)
    return np.stack([right, up, view])


def render_rgb(positions: np.ndarray, triangles: np.ndarray, width: int = 320, height: int = 240,
               elevation_deg: float = 50.0, azimuth_deg: float = 180.0, extent: float = 0.0) -> np.ndarray:
    """An (height, width, 3) uint8 image of the mesh (positions (N, 3) m, world frame, z up;
    triangles (T, 3) vertex indices) on the table z = 0, seen from the robots' side (azimuth 180:
    from -x, looking along +x) and from above at `elevation_deg`, orthographic. The view frames
    the garment with a margin (or a square of side `extent` m about its centre when > 0)."""
    x = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if width < 8 or height < 8:
        raise ValueError(f"render size must be at least 8x8 pixels, got {width}x{height}")
    img = np.empty((height, width, 3), dtype=np.uint8)
    img[:] = BACKGROUND_RGB
    finite = np.isfinite(x).all(axis=1)
    if len(tris) == 0 or not finite.any():
        return img
    cam = _camera(elevation_deg, azimuth_deg)
    centre = 0.5 * (x[finite].min(axis=0) + x[finite].max(axis=0))
    centre[2] = 0.0
    half = 0.5 * extent if extent > 0 else 0.6 * max(np.ptp(x[finite], axis=0).max(), 0.1)
    scale = 0.5 * min(width, height) / half  # pixels per metre

    def to_pixels(p):
        q = (p - centre) @ cam.T
        return np.stack([0.5 * width + scale * q[:, 0], 0.5 * height - scale * q[:, 1], q[:, 2]], axis=1)

    # The table: a quad under the garment, 1.5 view widths wide.
    s = 1.5 * half * max(width, height) / min(width, height)
    quad = to_pixels(centre + np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]]))
    _fill(img, quad[[0, 1, 2]], TABLE_RGB)
    _fill(img, quad[[0, 2, 3]], TABLE_RGB)

    keep = finite[tris].all(axis=1)
    tris = tris[keep]
    px = to_pixels(np.where(finite[:, None], x, 0.0))
    p0, p1, p2 = x[tris[:, 0]], x[tris[:, 1]], x[tris[:, 2]]
    n = np.cross(p1 - p0, p2 - p0)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    light = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    shade = 0.35 + 0.65 * np.abs(n @ light)  # two-sided cloth
    depth = px[tris, 2].mean(axis=1)
    for t in np.argsort(-depth):  # far to near
        _fill(img, px[tris[t]], CLOTH_RGB * shade[t])
    return img


def _fill(img: np.ndarray, tri: np.ndarray, rgb: np.ndarray) -> None:
    """Paints the pixels whose centres lie in the 2-D triangle tri (3, >= 2) pixel coordinates."""
    h, w = img.shape[:2]
    x0, x1 = int(max(np.floor(tri[:, 0].min()), 0)), int(min(np.ceil(tri[:, 0].max()), w - 1))
    y0, y1 = int(max(np.floor(tri[:, 1].min()), 0)), int(min(np.ceil(tri[:, 1].max()), h - 1))
    if x0 > x1 or y0 > y1:
        return
    (ax, ay), (bx, by), (cx, cy) = tri[0, :2], tri[1, :2], tri[2, :2]
    area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    if abs(area) < 1e-12:
        return
    gx, gy = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5)
    w0 = ((bx - gx) * (cy - gy) - (by - gy) * (cx - gx)) / area
    w1 = ((cx - gx) * (ay - gy) - (cy - gy) * (ax - gx)) / area
    inside = (w0 >= 0) & (w1 >= 0) & (w0 + w1 <= 1)
    img[y0:y1 + 1, x0:x1 + 1][inside] = np.clip(rgb, 0, 255).astype(np.uint8)
