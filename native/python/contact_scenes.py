"""Objects standing on their receiver (issue 12): a box on a floor, a table on a floor, a bookcase against a
wall, each under one light-only square lamp, with the exact direct light. The objects are black and only one
surface reflects, so that surface's light is direct only and the exact answer is a plain integral over the lamp
with ray-box visibility, independent of the solver."""
import numpy as np

import _native

LAMP, HEIGHT, EMIT, RHO = 0.25, 2.5, 10.0, 0.7   # lamp half side, height, exitance, receiver albedo


def box_quads(lo, hi):
    """The six faces of an axis-aligned box, counter-clockwise seen from outside."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    return [[(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],    # top
            [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],    # bottom
            [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],    # -y
            [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],    # +y
            [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],    # -x
            [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)]]    # +x


def grid_quads(origin, e1, e2, n):
    o, e1, e2 = (np.asarray(v, float) for v in (origin, e1, e2))
    return [[tuple(o + e1 * (i + a) / n + e2 * (j + b) / n) for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))]
            for j in range(n) for i in range(n)]


class ContactScene:
    """`receiver`: (origin, e1, e2) of the reflecting rectangle (front side along e1 x e2), in `faces` x `faces`
    faces; `boxes`: black boxes (lo, hi) touching it; the lamp at `lamp_centre`, facing down."""

    def __init__(self, receiver, boxes, lamp_centre=(0.0, 0.0, HEIGHT), faces=16):
        self.receiver, self.boxes = receiver, [(np.array(lo, float), np.array(hi, float)) for lo, hi in boxes]
        self.lamp_centre = np.array(lamp_centre, float)
        verts, polys, refl, emis, obj = [], [], [], [], []

        def quad(corners, rho, emit, o):
            polys.append([len(verts) + k for k in range(4)])
            verts.extend(corners)
            refl.append([rho] * 3)
            emis.append([emit] * 3)
            obj.append(o)
        for q in grid_quads(*receiver, faces):
            quad(q, RHO, 0, 0)
        for lo, hi in boxes:
            for q in box_quads(lo, hi):
                quad(q, 0, 0, 1)
        cx, cy, cz = lamp_centre
        L = LAMP
        quad([(cx - L, cy - L, cz), (cx - L, cy + L, cz), (cx + L, cy + L, cz), (cx + L, cy - L, cz)], 0, EMIT, 2)
        flags = np.zeros(len(polys), np.uint8)
        flags[-1] = _native.LIGHT_ONLY
        self.args = (np.array(verts, np.float32), np.array(polys, np.int32), np.array(refl, np.float32),
                     np.array(emis, np.float32), flags, np.array(obj, np.int32), ["Receiver", "Object", "Lamp"])
        o, e1, e2 = (np.asarray(v, float) for v in receiver)
        self.normal = np.cross(e1, e2) / np.linalg.norm(np.cross(e1, e2))

    def sample_points(self, n=48):
        """An n x n grid over the receiver, off its face boundaries, without the points a box covers."""
        o, e1, e2 = (np.asarray(v, float) for v in self.receiver)
        t = (np.arange(n) + 0.5) / n
        pts = np.array([o + e1 * a + e2 * b for b in t for a in t])
        inside = np.zeros(len(pts), bool)
        for lo, hi in self.boxes:
            inside |= np.all((pts > lo - 1e-9) & (pts < hi + 1e-9), axis=1)
        return pts[~inside]

    def under_points(self, k=5):
        """Points of the receiver covered by the boxes that stand on it, inset by 10 % of the box."""
        d = np.dot(np.asarray(self.receiver[0], float), self.normal)
        out = []
        for lo, hi in self.boxes:
            if abs(min(np.dot(lo, self.normal), np.dot(hi, self.normal)) - d) > 1e-9:
                continue  # not touching the receiver
            for f in np.stack(np.meshgrid(*[np.linspace(0.1, 0.9, k)] * 3), -1).reshape(-1, 3):
                p = lo + (hi - lo) * f
                out.append(p - self.normal * (np.dot(p, self.normal) - d))
        return np.unique(np.round(np.array(out), 9), axis=0)

    def exact_radiance(self, pts, m=40):
        """rho/pi * B_e * form factor of the lamp's visible part, midpoint rule on m x m lamp cells, every ray
        tested against every box (slab test)."""
        u = ((np.arange(m) + 0.5) / m * 2 - 1) * LAMP
        lx, ly = [a.ravel() for a in np.meshgrid(u, u)]
        q = np.stack([lx + self.lamp_centre[0], ly + self.lamp_centre[1], np.full(lx.shape, self.lamp_centre[2])], 1)
        dA = (2 * LAMP / m) ** 2
        out = np.empty(len(pts))
        for i, p in enumerate(np.asarray(pts, float)):
            d = q - p
            r2 = (d * d).sum(1)
            cos_r = np.clip(d @ self.normal, 0, None) / np.sqrt(r2)
            cos_s = np.clip(d[:, 2], 0, None) / np.sqrt(r2)
            seen = np.ones(len(q), bool)
            with np.errstate(divide="ignore", invalid="ignore"):
                for lo, hi in self.boxes:
                    t0, t1 = (lo - p) / d, (hi - p) / d
                    tmin = np.nanmax(np.minimum(t0, t1), 1)
                    tmax = np.nanmin(np.maximum(t0, t1), 1)
                    seen &= ~((tmax > np.maximum(tmin, 1e-9)) & (tmin < 1))
            out[i] = RHO * EMIT * (cos_r * cos_s / (np.pi * r2) * dA * seen).sum() / np.pi
        return out


def box_on_floor():
    return ContactScene(((-2, -2, 0), (4, 0, 0), (0, 4, 0)), [((0.3, -0.3, 0), (0.9, 0.3, 0.6))])


def table_on_floor():
    top = ((-0.6, -0.4, 0.71), (0.6, 0.4, 0.75))
    legs = [((x, y, 0), (x + 0.05, y + 0.05, 0.71)) for x in (-0.55, 0.5) for y in (-0.35, 0.3)]
    return ContactScene(((-2, -2, 0), (4, 0, 0), (0, 4, 0)), [top] + legs, lamp_centre=(0.3, 0.2, HEIGHT))


def bookcase_against_wall():
    """A 2 x 2.2 m wall (x = -1, facing +x) lit by a ceiling lamp 0.8 m from it; a 0.3 m deep bookcase touching
    the wall (its back in the wall's plane)."""
    wall = ((-1, -1, 0), (0, 2, 0), (0, 0, 2.2))
    return ContactScene(wall, [((-1, -0.5, 0), (-0.7, 0.5, 1.8))], lamp_centre=(-0.2, 0.0, HEIGHT))


# Walls under a ceiling lamp (wall_links): a 4 x 2.8 m wall (x = -1, facing +x) reaching above the lamp's plane,
# the lamp 1.6 m from it, and black furniture in front of it.
WALL = ((-1, -2, 0), (0, 4, 0), (0, 0, 2.8))
WALL_LAMP = (0.6, 0.0, HEIGHT)


def shelf_near_wall():
    """A 1 cm plate (a shelf or a table top without legs) 0.74 m up, 0.25 m clear of the wall."""
    return ContactScene(WALL, [((-0.75, -0.6, 0.74), (-0.15, 0.6, 0.75))], lamp_centre=WALL_LAMP)


def shelf_against_wall():
    """The same plate, its back edge on the wall."""
    return ContactScene(WALL, [((-1.0, -0.6, 0.74), (-0.6, 0.6, 0.75))], lamp_centre=WALL_LAMP)


def box_near_wall():
    """A 1.2 m tall box (a cupboard) 0.3 m clear of the wall: its face toward the lamp is tall."""
    return ContactScene(WALL, [((-0.7, -0.3, 0), (-0.4, 0.3, 1.2))], lamp_centre=WALL_LAMP)


def table_near_wall():
    """A table (top and four 5 cm legs) 0.25 m clear of the wall."""
    top = ((-0.75, -0.6, 0.71), (-0.15, 0.6, 0.75))
    legs = [((x, y, 0), (x + 0.05, y + 0.05, 0.71)) for x in (-0.75, -0.2) for y in (-0.6, 0.55)]
    return ContactScene(WALL, [top] + legs, lamp_centre=WALL_LAMP)
