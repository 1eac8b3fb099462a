// ARKit weights (core/arkit.hpp): Apple's names, the map from the ICT head's expression shapes
// (every one maps, no Apple name twice, left is the face's left, split shapes merged), the
// shapes held at 0, and the four weights a model without expression shapes derives from the
// signals. The weights of a fit are tested in test_expression_fit.cpp.
#include "allocation_counter.hpp"
#include "build_paths.hpp"
#include "core/arkit.hpp"
#include "core/drive_signals.hpp"
#include "core/fitting.hpp"
#include "firmware_app/config/model_files.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

const MorphableModel& ict_model() {
  static const MorphableModel model = load_model_file(std::filesystem::path(test::kModelDir) / "ict_face_light.lpm");
  return model;
}

int apple(std::string_view name) { return *arkit_index(name); }

TEST(ArkitNames, ApplesFiftyTwoInApplesOrder) {
  EXPECT_EQ(std::set<std::string_view>(kArkitNames.begin(), kArkitNames.end()).size(), 52u);
  EXPECT_EQ(kArkitNames.front(), "eyeBlinkLeft");
  EXPECT_EQ(apple("eyeBlinkRight"), 7);
  EXPECT_EQ(apple("jawForward"), 14);
  EXPECT_EQ(apple("jawOpen"), 17);
  EXPECT_EQ(apple("mouthClose"), 18);
  EXPECT_EQ(apple("browDownLeft"), 41);
  EXPECT_EQ(apple("cheekPuff"), 46);
  EXPECT_EQ(kArkitNames.back(), "tongueOut");
  EXPECT_FALSE(arkit_index("mouthSmile_L"));
}

TEST(ArkitMap, EveryIctShapeMapsAndNoAppleNameTwice) {
  const MorphableModel& model = ict_model();
  ASSERT_EQ(model.num_expressions(), 53);
  std::multiset<int> claimed;
  for (const std::string& name : model.expression_names) {
    const auto a = arkit_index_of_expression(name);
    ASSERT_TRUE(a) << name << " has no Apple name";
    claimed.insert(*a);
  }
  // 52 Apple names less tongueOut (ICT has none); browInnerUp and cheekPuff from two halves.
  for (int a = 0; a < kNumArkit; ++a) {
    const std::string_view name = kArkitNames[static_cast<std::size_t>(a)];
    const std::size_t expected = name == "tongueOut" ? 0 : name == "browInnerUp" || name == "cheekPuff" ? 2 : 1;
    EXPECT_EQ(claimed.count(a), expected) << name;
  }
  const ArkitMap map(model.expression_names);
  EXPECT_TRUE(map.from_fit());
  const auto source_name = [&](int e) { return e < 0 ? std::string("-") : model.expression_names[e]; };
  const auto sources = [&](std::string_view name) {
    const auto [first, second] = map.sources(apple(name));
    return source_name(first) + " " + source_name(second);
  };
  EXPECT_EQ(sources("jawOpen"), "jawOpen -");
  EXPECT_EQ(sources("mouthSmileLeft"), "mouthSmile_L -");
  EXPECT_EQ(sources("mouthSmileRight"), "mouthSmile_R -");
  EXPECT_EQ(sources("jawLeft"), "jawLeft -");
  EXPECT_EQ(sources("browInnerUp"), "browInnerUp_L browInnerUp_R");
  // Held at 0: what a 68-point fit cannot observe, and the name without a shape.
  for (const char* held :
       {"cheekPuff", "tongueOut", "eyeLookDownLeft", "eyeLookInRight", "eyeLookOutLeft", "eyeLookUpRight"})
    EXPECT_EQ(sources(held), "- -") << held;
  int mapped = 0;
  for (int a = 0; a < kNumArkit; ++a) mapped += map.sources(a)[0] >= 0;
  EXPECT_EQ(mapped, 42) << "52 less the 8 eye-gaze shapes, cheekPuff and tongueOut";
}

// Apple's Left and Right are the face's own (ARFaceAnchor.BlendShapeLocation); in every lipdrive
// model x points to the subject's left. A shape of one side (ICT's `_L`, `_R`) moves that half of
// the face most; jawLeft and mouthLeft move towards the face's left.
TEST(ArkitMap, LeftIsTheFacesLeft) {
  const MorphableModel& model = ict_model();
  int checked = 0;
  for (int e = 0; e < model.num_expressions(); ++e) {
    const std::string& name = model.expression_names[static_cast<std::size_t>(e)];
    const std::string_view apple_name = kArkitNames[static_cast<std::size_t>(*arkit_index_of_expression(name))];
    double moved_left = 0, moved_right = 0, shift_x = 0;  // displacement on either side of the midline
    for (int v = 0; v < model.num_vertices(); ++v) {
      const auto moved = model.expressions.block<3, 1>(3 * v, e);
      (model.mean[3 * v] > 0 ? moved_left : moved_right) += moved.norm();
      shift_x += moved.x();
    }
    if (name.ends_with("_L") || name.ends_with("_R")) {
      const bool left = name.ends_with("_L");
      EXPECT_GT(left ? moved_left : moved_right, 2 * (left ? moved_right : moved_left)) << name;
      EXPECT_TRUE(apple_name.ends_with(left ? "Left" : "Right") || !apple_name.ends_with(left ? "Right" : "Left"))
          << name << " -> " << apple_name;
      ++checked;
    } else if (apple_name.ends_with("Left") || apple_name.ends_with("Right")) {
      EXPECT_GT(apple_name.ends_with("Left") ? shift_x : -shift_x, 0) << name;
      ++checked;
    }
  }
  EXPECT_EQ(checked, 44) << "40 shapes of one side (4 of them halves), jawLeft, jawRight, mouthLeft, mouthRight";
}

TEST(ArkitMap, RejectsTwoShapesForOneNameAndALoneHalf) {
  for (const std::vector<std::string>& names : std::vector<std::vector<std::string>>{
           {"jawOpen", "jawOpen"}, {"browInnerUp", "browInnerUp_L"}, {"browInnerUp_R", "browInnerUp"}, {"cheekPuff_L"}})
    EXPECT_THROW(ArkitMap{names}, std::invalid_argument) << names.front();
  EXPECT_NO_THROW(ArkitMap(std::vector<std::string>{"jawOpen", "lipsTogether"})) << "a name that is no ARKit shape";
}

DriveSignals signals(float open, float protrusion, float seal) {
  DriveSignals s;
  s[Signal::kOpen] = open;
  s[Signal::kProtrusion] = protrusion;
  s[Signal::kSeal] = seal;
  return s;
}

float weight(const DriveSignals& s, std::string_view name) { return s[arkit_signal(apple(name))]; }

// A model without expression shapes: the four mouth weights from the signals, the rest 0.
TEST(ArkitSignals, WithoutExpressionShapesFourMouthWeightsComeFromTheSignals) {
  const ArkitMap map(std::vector<std::string>{});
  EXPECT_FALSE(map.from_fit());
  DriveSignals oh = signals(0.8f, 0.5f, 0);
  for (int a = 0; a < kNumArkit; ++a) oh[arkit_signal(a)] = 0.7f;  // the last frame's
  set_arkit_signals(map, {}, oh);
  EXPECT_FLOAT_EQ(weight(oh, "jawOpen"), 0.8f);
  EXPECT_FLOAT_EQ(weight(oh, "mouthFunnel"), 0.4f);    // forward and open
  EXPECT_NEAR(weight(oh, "mouthPucker"), 0.1f, 1e-6);  // forward and closed
  EXPECT_FLOAT_EQ(weight(oh, "mouthClose"), 0);
  for (const char* other : {"mouthSmileLeft", "eyeBlinkRight", "browInnerUp", "tongueOut"})
    EXPECT_EQ(weight(oh, other), 0) << other;
  DriveSignals press = signals(0, 0, 0.9f);
  set_arkit_signals(map, {}, press);
  EXPECT_FLOAT_EQ(weight(press, "mouthClose"), 0.9f);  // the lips touch
  DriveSignals over = signals(2, 2, 3);
  set_arkit_signals(map, {}, over);
  for (const float w : over.arkit()) {
    EXPECT_GE(w, 0);
    EXPECT_LE(w, 1);
  }
}

TEST(ArkitSignals, FromTheFitMergedHalvesAreTheirMeanAndNothingIsAllocated) {
  const MorphableModel& model = ict_model();
  const ArkitMap map(model.expression_names);
  FitOutput::Expressions w = FitOutput::Expressions::Zero();
  const auto set = [&](std::string_view name, double value) { w[*model.expression_index(name)] = value; };
  set("jawOpen", 0.6);
  set("mouthSmile_L", 0.5);
  set("browInnerUp_L", 0.2);
  set("browInnerUp_R", 0.6);
  set("cheekPuff_L", 0.9);  // never fitted; held at 0 whatever it holds
  DriveSignals s = signals(0.1f, 0.3f, 0);
  test::count_allocations_on_this_thread(true);
  const long before = test::allocation_count();
  set_arkit_signals(map, std::span<const double>(w.data(), w.size()), s);
  EXPECT_EQ(test::allocation_count() - before, 0);
  test::count_allocations_on_this_thread(false);
  EXPECT_FLOAT_EQ(weight(s, "jawOpen"), 0.6f) << "from the fit, not the open signal";
  EXPECT_FLOAT_EQ(weight(s, "mouthSmileLeft"), 0.5f);
  EXPECT_FLOAT_EQ(weight(s, "mouthSmileRight"), 0);
  EXPECT_FLOAT_EQ(weight(s, "browInnerUp"), 0.4f);
  EXPECT_FLOAT_EQ(weight(s, "cheekPuff"), 0);
  EXPECT_FLOAT_EQ(weight(s, "mouthPucker"), 0) << "no protrusion-derived weight for a fitted model";
  EXPECT_FLOAT_EQ(weight(s, "mouthClose"), 0) << "lips apart (seal 0): the fit's mouthClose";
}

// Lips the pixels see touching are closed over the fitted jaw (ARKit's mouthClose: the lips
// together over an open jaw), in proportion to the seal; a fitted mouthClose above that stays.
TEST(ArkitSignals, LipsThatTouchAreClosedOverTheFittedJaw) {
  const MorphableModel& model = ict_model();
  const ArkitMap map(model.expression_names);
  FitOutput::Expressions w = FitOutput::Expressions::Zero();
  w[*model.expression_index("jawOpen")] = 0.4;
  for (const auto& [seal, close] : {std::pair{1.0f, 0.4f}, std::pair{0.5f, 0.2f}, std::pair{0.0f, 0.0f}}) {
    DriveSignals s = signals(0.1f, 0.3f, seal);
    set_arkit_signals(map, std::span<const double>(w.data(), w.size()), s);
    EXPECT_FLOAT_EQ(weight(s, "jawOpen"), 0.4f) << "the jaw as fitted";
    EXPECT_FLOAT_EQ(weight(s, "mouthClose"), close) << "seal " << seal;
  }
  w[*model.expression_index("mouthClose")] = 0.3;
  DriveSignals half = signals(0.1f, 0.3f, 0.5f);
  set_arkit_signals(map, std::span<const double>(w.data(), w.size()), half);
  EXPECT_FLOAT_EQ(weight(half, "mouthClose"), 0.3f) << "the fit's own closure, larger than 0.5 x 0.4";
}

}  // namespace
}  // namespace lipdrive
