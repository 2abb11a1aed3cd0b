// The table of settings (PENUMBRA_SETTINGS): every row is a well-formed interval holding its default,
// keys are unique, and the solver refuses just outside each bound with the row's own words.
#include "solve/settings.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>
#include <type_traits>

#include "penumbra.h"

namespace penumbra {
namespace {

TEST(Settings, EveryRowIsAnIntervalHoldingItsDefault) {
    std::set<std::string> keys;
    const Settings defaults;
    forEachSetting(defaults, [&](const SettingInfo& info, const auto& value) {
        using T = std::decay_t<decltype(value)>;
        EXPECT_TRUE(keys.insert(info.key).second) << "duplicate key " << info.key;
        EXPECT_TRUE(info.lo == '[' || info.lo == '(') << info.key;
        EXPECT_TRUE(info.hi == ']' || info.hi == ')') << info.key;
        EXPECT_LE(info.min, info.max) << info.key;
        if constexpr (!std::is_same_v<T, bool>) {
            EXPECT_TRUE(info.contains(double(value))) << info.key;
        }
    });
    EXPECT_GT(keys.size(), 10u);
}

TEST(Settings, DescribeWritesTheInterval) {
    EXPECT_EQ((SettingInfo{"k", '[', 1, 256, ']'}).describe(true), "in [1, 256]");
    EXPECT_EQ((SettingInfo{"k", '(', 0, 1, ')'}).describe(false), "in (0, 1)");
    EXPECT_EQ((SettingInfo{"k", '(', 0, kNoBound, ')'}).describe(false), "a finite number > 0");
    EXPECT_EQ((SettingInfo{"k", '[', 0, kNoBound, ')'}).describe(false), "a finite number >= 0");
    EXPECT_EQ((SettingInfo{"k", '[', 1, kNoBound, ']'}).describe(true), "at least 1");
    EXPECT_FALSE((SettingInfo{"k", '(', 0, kNoBound, ')'}).contains(kNoBound));
    EXPECT_TRUE((SettingInfo{"k", '[', 1, kNoBound, ']'}).contains(kNoBound));
    EXPECT_FALSE((SettingInfo{"k", '[', 1, kNoBound, ']'}).contains(std::nan("")));
}

// solve() validates before it reads the scene, so an empty input is enough to see a setting refused.
TEST(Settings, SolveRefusesJustBelowEveryLowerBound) {
    Settings probe;
    forEachSetting(probe, [&](const SettingInfo& info, auto& member) {
        using T = std::decay_t<decltype(member)>;
        if constexpr (!std::is_same_v<T, bool>) {
            double below = info.lo == '(' ? info.min : std::nextafter(info.min, -kNoBound);
            if (std::is_integral_v<T> && info.lo == '[') below = info.min - 1;
            if (below < 0 && std::is_unsigned_v<T>) return;   // not representable
            const T saved = member;
            member = T(below);                  // probe differs from the defaults in this one setting
            try {
                solve(SceneInput{}, probe, nullptr);
                ADD_FAILURE() << info.key << " = " << below << " was accepted";
            } catch (const InputError& e) {
                EXPECT_EQ(std::string(e.what()), std::string("setting ") + info.key + " must be " +
                                                     info.describe(std::is_integral_v<T>));
            }
            member = saved;
        }
    });
}

}  // namespace
}  // namespace penumbra
