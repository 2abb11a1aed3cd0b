// Haines & Wallace shaft culling: the convex region between two boxes, bounded by their union box
// and by at most eight planes through pairs of parallel box edges. Every segment joining the two
// boxes lies inside it, so an occluder box classified Outside cannot block any of them.
#pragma once
#include <array>

#include "geometry/vec3.h"

namespace penumbra {

class Shaft {
public:
    enum Class { Outside, Overlap, Inside };
    Shaft(const Bounds& a, const Bounds& b);
    Class classify(const Bounds& box) const;
    int planes() const { return numPlanes_; }
    const Bounds& extent() const { return extent_; }

private:
    struct Plane {
        Vec3 n;
        double d;  // n . p + d > 0 is outside
    };
    Bounds a_, b_, extent_;
    std::array<Plane, 8> planes_;
    int numPlanes_ = 0;
};

}  // namespace penumbra
