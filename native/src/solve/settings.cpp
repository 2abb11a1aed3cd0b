#include "solve/settings.h"

#include <cstdio>

namespace penumbra {

namespace {

// %g for reals and the integer itself for integers, as settings_table.py's _number() writes them.
std::string number(double x, bool integer) {
    if (x == kNoBound) return "inf";
    char buf[64];
    if (integer) std::snprintf(buf, sizeof buf, "%lld", static_cast<long long>(x));
    else std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

}  // namespace

std::string SettingInfo::describe(bool integer) const {
    if (max == kNoBound) {
        if (hi == ')' && !integer)
            return std::string("a finite number ") + (lo == '(' ? "> " : ">= ") + number(min, false);
        return (lo == '(' ? "greater than " : "at least ") + number(min, integer);
    }
    return std::string("in ") + lo + number(min, integer) + ", " + number(max, integer) + hi;
}

}  // namespace penumbra
