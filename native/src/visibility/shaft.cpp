#include "visibility/shaft.h"

#include "geometry/box_tree.h"

namespace penumbra {

Shaft::Shaft(const Bounds& a, const Bounds& b) : a_(a), b_(b) {
    extent_ = a;
    extent_.extend(b);
    // owner[axis][side]: which box supplies the extreme coordinate (0 = a, 1 = b, -1 = both).
    int owner[3][2];
    for (int i = 0; i < 3; ++i) {
        owner[i][0] = a.lo[i] < b.lo[i] ? 0 : (b.lo[i] < a.lo[i] ? 1 : -1);
        owner[i][1] = a.hi[i] > b.hi[i] ? 0 : (b.hi[i] > a.hi[i] ? 1 : -1);
    }
    const Bounds* box[2] = {&a_, &b_};
    auto coord = [](const Bounds& bx, int axis, int side) { return side ? bx.hi[axis] : bx.lo[axis]; };
    for (int i = 0; i < 3; ++i)
        for (int si = 0; si < 2; ++si) {
            if (owner[i][si] != 0) continue;  // a's extreme on axis i
            for (int j = 0; j < 3; ++j) {
                if (j == i) continue;
                for (int sj = 0; sj < 2; ++sj) {
                    if (owner[j][sj] != 1) continue;  // paired with b's extreme on another axis
                    // The plane holds the edge of a at (i: side si, j: side sj) and the parallel edge
                    // of b at the same sides; it is parallel to the third axis.
                    double ai = coord(*box[0], i, si), aj = coord(*box[0], j, sj);
                    double bi = coord(*box[1], i, si), bj = coord(*box[1], j, sj);
                    double di = bi - ai, dj = bj - aj;
                    Vec3 n;
                    n[i] = dj;
                    n[j] = -di;
                    // Outward: away from the box interiors, i.e. toward side si on axis i.
                    if ((si ? 1.0 : -1.0) * n[i] < 0) n = -n;
                    double len = length(n);
                    if (!(len > 0) || numPlanes_ == 8) continue;
                    n = n / len;
                    Vec3 p;
                    p[i] = ai;
                    p[j] = aj;
                    planes_[numPlanes_++] = Plane{n, -dot(n, p)};
                }
            }
        }
}

Shaft::Class Shaft::classify(const Bounds& box) const {
    if (!overlaps(box, extent_)) return Outside;
    bool partial = !(box.lo.x >= extent_.lo.x && box.hi.x <= extent_.hi.x && box.lo.y >= extent_.lo.y &&
                     box.hi.y <= extent_.hi.y && box.lo.z >= extent_.lo.z && box.hi.z <= extent_.hi.z);
    for (int k = 0; k < numPlanes_; ++k) {
        const Plane& pl = planes_[k];
        Vec3 nearest, farthest;
        for (int c = 0; c < 3; ++c) {
            nearest[c] = pl.n[c] > 0 ? box.lo[c] : box.hi[c];
            farthest[c] = pl.n[c] > 0 ? box.hi[c] : box.lo[c];
        }
        if (dot(pl.n, nearest) + pl.d > 0) return Outside;
        if (dot(pl.n, farthest) + pl.d > 0) partial = true;
    }
    return partial ? Overlap : Inside;
}

}  // namespace penumbra
