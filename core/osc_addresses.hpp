// The OSC address scheme of the OSC output and the OSC control input (docs/osc.md).
//
// Every drive frame goes out as one bundle:
//   /lipdrive/frame i         the drive frame counter (+1 per drive frame; a gap is a lost frame)
//   /lipdrive/status i        the status word (the Modbus status register's bits)
//   /lipdrive/<channel> f     each configured channel, in output units
//   /lipdrive/timecode s      "HH:MM:SS:FF" of the frame, when a timecode source is set
//   /found i                  FaceOSC: 1 while a face is tracked
//   /gesture/mouth/width f    FaceOSC's mouth gestures, in FaceOSC's ranges
//   /gesture/mouth/height f
//   /gesture/jaw f
//   /<ARKit name> f           the 52 ARKit blendshape weights in [0, 1] under Apple's names, in
//                             Apple's order (core/arkit.hpp)
// Control messages (to [osc_control]): Live Link Face's /RecordStart s i, /RecordStop,
// /Slate s, /Take i, and /lipdrive/calibrate, /lipdrive/output_enable i.
#pragma once

#include "core/drive_signals.hpp"

#include <string>
#include <string_view>

namespace lipdrive::osc {

inline constexpr std::string_view kChannelPrefix = "/lipdrive/";
inline constexpr std::string_view kFrame = "/lipdrive/frame";
inline constexpr std::string_view kStatus = "/lipdrive/status";
inline constexpr std::string_view kTimecode = "/lipdrive/timecode";
inline constexpr std::string_view kFound = "/found";
inline constexpr std::string_view kMouthWidth = "/gesture/mouth/width";
inline constexpr std::string_view kMouthHeight = "/gesture/mouth/height";
inline constexpr std::string_view kJaw = "/gesture/jaw";

inline constexpr std::string_view kRecordStart = "/RecordStart";
inline constexpr std::string_view kRecordStop = "/RecordStop";
inline constexpr std::string_view kSlate = "/Slate";
inline constexpr std::string_view kTake = "/Take";
inline constexpr std::string_view kCalibrate = "/lipdrive/calibrate";
inline constexpr std::string_view kOutputEnable = "/lipdrive/output_enable";

/// Whether `name` can be one part of an OSC address: printable ASCII other than space and
/// the characters OSC reserves for patterns and separators (# * , / ? [ ] { }).
bool is_address_part(std::string_view name);

/// "/lipdrive/<channel>".
std::string channel_address(std::string_view channel);

/// "/<ARKit name>", e.g. "/jawOpen".
std::string arkit_address(std::string_view arkit_name);

/// FaceOSC's mouth gestures from the calibrated signals, scaled into the ranges FaceOSC's own
/// values take (distances in its tracker's model units: mouth width about 10..18, inner
/// mouth height 0..7, nose to chin 20..25), so sketches written for FaceOSC work unchanged.
struct FaceOscGestures {
  float mouth_width = 0, mouth_height = 0, jaw = 0;
};
FaceOscGestures face_osc_gestures(const DriveSignals& signals);

}  // namespace lipdrive::osc
