// `lipdrive plot`: trajectories of CSV columns over time as a PNG, one panel per
// column, one coloured line per file, gaps where a value is missing.
#include "drivers/image_codec.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/cli/options.hpp"
#include "firmware_app/tables/csv_table.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <numeric>
#include <string>
#include <unordered_set>
#include <vector>

namespace lipdrive {
namespace {

struct PlotOptions {
  std::vector<std::string> files;
  std::vector<std::string> columns;
  std::string out;
  int width = 1000;
  int height = 0;  // 0: sized from the number of panels
  std::string title;
};

/// One file's data: the x value and each requested column, row by row.
struct Trajectories {
  std::string label;
  std::vector<double> x;
  std::vector<std::vector<double>> columns;
};

struct Range {
  double low = 0;
  double high = 1;
};

// Tableau 10 palette (BGR): distinct, and readable on white.
const std::vector<cv::Scalar> kLineColours = {{180, 119, 31},  {14, 127, 255}, {44, 160, 44},   {40, 39, 214},
                                              {189, 103, 148}, {75, 86, 140},  {194, 119, 227}, {127, 127, 127},
                                              {34, 189, 188},  {207, 190, 23}};
const cv::Scalar kBackground{255, 255, 255};
const cv::Scalar kGrid{230, 230, 230};
const cv::Scalar kFrame{110, 110, 110};
const cv::Scalar kText{40, 40, 40};
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kTickFontScale = 0.42;
constexpr double kLabelFontScale = 0.5;
constexpr double kTitleFontScale = 0.65;

// Layout in pixels.
constexpr int kMarginLeft = 72, kMarginRight = 24, kMarginTop = 12, kMarginBottom = 50;
constexpr int kTitleHeight = 32, kLegendRowHeight = 24, kPanelHeaderHeight = 22, kPanelGap = 14;
constexpr int kDefaultPanelHeight = 240;
// The largest width or height of the image, given or computed: 10000 x 10000 BGR is 300 MB.
constexpr int kMaxImageSide = 10000;

cv::Size text_size(const std::string& text, double scale) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, 1, &baseline);
}

void put_text(cv::Mat& image, const std::string& text, cv::Point origin, double scale,
              const cv::Scalar& colour = kText) {
  cv::putText(image, text, origin, kFont, scale, colour, 1, cv::LINE_AA);
}

/// Heckbert's "nice numbers" (Graphics Gems, 1990): 1, 2 or 5 times a power of ten
/// near x, rounded to nearest or taken as the ceiling.
double nice_number(double x, bool round_to_nearest) {
  const double power = std::pow(10.0, std::floor(std::log10(x)));
  const double fraction = x / power;
  double nice = 10;
  if (round_to_nearest) {
    nice = fraction < 1.5 ? 1 : fraction < 3 ? 2 : fraction < 7 ? 5 : 10;
  } else {
    nice = fraction <= 1 ? 1 : fraction <= 2 ? 2 : fraction <= 5 ? 5 : 10;
  }
  return nice * power;
}

/// Tick spacing for about `count` ticks over the range (Heckbert's loose labelling).
double tick_step(const Range& range, int count) {
  return nice_number(nice_number(range.high - range.low, false) / (count - 1), true);
}

/// The multiples of `step` within the range, each worked out from its index (adding a step
/// below the values' rounding would never pass the range's end), at most kMaxTicks.
std::vector<double> ticks_within(const Range& range, double step) {
  constexpr double kMaxTicks = 100;
  std::vector<double> ticks;
  const double tolerance = step * 1e-9;
  const double first = std::ceil(range.low / step);
  const double count = std::min(std::floor((range.high + tolerance) / step) - first + 1, kMaxTicks);
  for (int i = 0; i < count; ++i) {
    const double tick = (first + i) * step;
    ticks.push_back(std::abs(tick) < tolerance ? 0.0 : tick);
  }
  return ticks;
}

std::string tick_label(double value, double step) {
  const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  return fmt::format("{:.{}f}", value, decimals);
}

/// The finite extent of some series, padded so lines do not run along the frame;
/// a constant series (or one that varies only in the last digits of its values) gets a band
/// around its value, no data gets [0, 1].
Range padded_range(const std::vector<const std::vector<double>*>& series, double padding) {
  double low = std::numeric_limits<double>::infinity();
  double high = -low;
  for (const auto* values : series) {
    for (double v : *values) {
      if (!std::isfinite(v)) continue;
      low = std::min(low, v);
      high = std::max(high, v);
    }
  }
  if (low > high) return {0, 1};
  if (high - low <= std::max(std::abs(low), std::abs(high)) * 1e-9) {
    const double half_band = low == 0 ? 0.5 : std::abs(low) * 0.1;
    return {low - half_band, high + half_band};
  }
  const double pad = (high - low) * padding;
  return {low - pad, high + pad};
}

double to_pixel(double value, const Range& range, int pixel_low, int pixel_high) {
  return pixel_low + (value - range.low) / (range.high - range.low) * (pixel_high - pixel_low);
}

/// Legend labels: file names, or the paths as given when two files share a name.
std::vector<std::string> legend_labels(const std::vector<std::string>& files) {
  std::vector<std::string> names;
  for (const auto& file : files) names.push_back(std::filesystem::path(file).filename().string());
  std::vector<std::string> sorted = names;
  std::sort(sorted.begin(), sorted.end());
  const bool unique = std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end();
  return unique ? names : files;
}

/// Abscissa: time_s when every file has it, else frame, so all lines share one axis.
std::string x_column(const std::vector<CsvTable>& tables) {
  const bool all_timed =
      std::all_of(tables.begin(), tables.end(), [](const CsvTable& t) { return has_column(t, "time_s"); });
  return all_timed ? "time_s" : "frame";
}

Trajectories read_trajectories(const CsvTable& table, const std::string& x_name,
                               const std::vector<std::string>& columns, std::string label) {
  Trajectories data{std::move(label), numeric_column(table, x_name), {}};
  for (const auto& column : columns) data.columns.push_back(numeric_column(table, column));
  // Draw in x order even if the rows are not.
  std::vector<std::size_t> order(data.x.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return data.x[a] < data.x[b]; });
  auto reorder = [&order](const std::vector<double>& values) {
    std::vector<double> sorted;
    for (std::size_t i : order) sorted.push_back(values[i]);
    return sorted;
  };
  data.x = reorder(data.x);
  for (auto& values : data.columns) values = reorder(values);
  return data;
}

/// One line per run of finite points; a lone point between gaps becomes a dot so
/// that it stays visible.
void draw_series(cv::Mat& image, const std::vector<double>& x, const std::vector<double>& y, const Range& x_range,
                 const Range& y_range, const cv::Rect& area, const cv::Scalar& colour) {
  // Sub-pixel coordinates: OpenCV's fixed-point shift keeps anti-aliased lines smooth.
  constexpr int kShift = 4;
  constexpr double kScale = 1 << kShift;
  std::vector<cv::Point> run;
  auto flush = [&] {
    if (run.size() == 1) cv::circle(image, run[0], 2 << kShift, colour, cv::FILLED, cv::LINE_AA, kShift);
    if (run.size() > 1) cv::polylines(image, run, false, colour, 2, cv::LINE_AA, kShift);
    run.clear();
  };
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) {
      flush();
      continue;
    }
    const double px = to_pixel(x[i], x_range, area.x, area.x + area.width);
    const double py = to_pixel(y[i], y_range, area.y + area.height, area.y);
    run.emplace_back(cvRound(px * kScale), cvRound(py * kScale));
  }
  flush();
}

void draw_panel(cv::Mat& image, const cv::Rect& area, const std::string& name, const Range& x_range, double x_step,
                const Range& y_range, bool x_labels, const std::string& x_name) {
  const int ticks_y = std::clamp(area.height / 40, 2, 8);
  const double y_step = tick_step(y_range, ticks_y);
  for (double tick : ticks_within(y_range, y_step)) {
    const int py = cvRound(to_pixel(tick, y_range, area.y + area.height, area.y));
    cv::line(image, {area.x, py}, {area.x + area.width, py}, kGrid, 1);
    cv::line(image, {area.x - 4, py}, {area.x, py}, kFrame, 1);
    const std::string label = tick_label(tick, y_step);
    const cv::Size size = text_size(label, kTickFontScale);
    put_text(image, label, {area.x - 8 - size.width, py + size.height / 2}, kTickFontScale);
  }
  for (double tick : ticks_within(x_range, x_step)) {
    const int px = cvRound(to_pixel(tick, x_range, area.x, area.x + area.width));
    cv::line(image, {px, area.y}, {px, area.y + area.height}, kGrid, 1);
    cv::line(image, {px, area.y + area.height}, {px, area.y + area.height + 4}, kFrame, 1);
    if (!x_labels) continue;
    const std::string label = tick_label(tick, x_step);
    const cv::Size size = text_size(label, kTickFontScale);
    put_text(image, label, {px - size.width / 2, area.y + area.height + 8 + size.height}, kTickFontScale);
  }
  cv::rectangle(image, area, kFrame, 1);
  put_text(image, name, {area.x, area.y - 7}, kLabelFontScale);
  if (x_labels) {
    const std::string label = x_name == "time_s" ? "time (s)" : "frame";
    const cv::Size size = text_size(label, kLabelFontScale);
    put_text(image, label, {area.x + (area.width - size.width) / 2, area.y + area.height + 40}, kLabelFontScale);
  }
}

constexpr int kSwatch = 26, kSwatchGap = 6, kEntryGap = 22;

/// Where each legend entry starts, relative to the legend's top-left corner:
/// entries flow left to right and wrap to a new row at the right margin.
std::vector<cv::Point> legend_layout(const std::vector<Trajectories>& files, int width) {
  const int row_width = width - kMarginLeft - kMarginRight;
  std::vector<cv::Point> origins;
  cv::Point next{0, 0};
  for (const auto& file : files) {
    const int entry_width = kSwatch + kSwatchGap + text_size(file.label, kLabelFontScale).width;
    if (next.x > 0 && next.x + entry_width > row_width) next = {0, next.y + kLegendRowHeight};
    origins.push_back(next);
    next.x += entry_width + kEntryGap;
  }
  return origins;
}

int legend_height(const std::vector<cv::Point>& layout) {
  return layout.empty() ? 0 : layout.back().y + kLegendRowHeight;
}

void draw_legend(cv::Mat& image, const std::vector<Trajectories>& files, const std::vector<cv::Point>& layout,
                 int top) {
  for (std::size_t i = 0; i < files.size(); ++i) {
    const int x = kMarginLeft + layout[i].x;
    const int middle = top + layout[i].y + kLegendRowHeight / 2;
    cv::line(image, {x, middle}, {x + kSwatch, middle}, kLineColours[i % kLineColours.size()], 3, cv::LINE_AA);
    put_text(image, files[i].label,
             {x + kSwatch + kSwatchGap, middle + text_size(files[i].label, kLabelFontScale).height / 2},
             kLabelFontScale);
  }
}

cv::Mat render_plot(const std::vector<Trajectories>& files, const PlotOptions& options, const std::string& x_name) {
  const int panels = static_cast<int>(options.columns.size());
  const int title_height = options.title.empty() ? 0 : kTitleHeight;
  const std::vector<cv::Point> legend = legend_layout(files, options.width);
  const int header = kMarginTop + title_height + legend_height(legend) + 6;
  const int height = options.height > 0 ? options.height
                                        : header + kMarginBottom + panels * (kDefaultPanelHeight + kPanelHeaderHeight) +
                                              (panels - 1) * kPanelGap;
  if (height > kMaxImageSide) {
    const int fit =
        (kMaxImageSide - header - kMarginBottom + kPanelGap) / (kDefaultPanelHeight + kPanelHeaderHeight + kPanelGap);
    throw CommandError(fmt::format("--columns: {} panels of {} px make an image {} px high, more than {} px ({} panels "
                                   "fit); plot fewer columns or pass --height",
                                   panels, kDefaultPanelHeight, height, kMaxImageSide, fit),
                       kExitUsage);
  }
  const int panel_height = (height - header - kMarginBottom - (panels - 1) * kPanelGap) / panels - kPanelHeaderHeight;
  const int panel_width = options.width - kMarginLeft - kMarginRight;
  if (panel_height < 40 || panel_width < 100) {
    throw CommandError(
        fmt::format("--width/--height: {}x{} pixels is too small for {} panel(s)", options.width, height, panels),
        kExitUsage);
  }

  cv::Mat image(height, options.width, CV_8UC3, kBackground);
  if (!options.title.empty()) {
    const cv::Size size = text_size(options.title, kTitleFontScale);
    put_text(image, options.title, {(options.width - size.width) / 2, kMarginTop + size.height + 4}, kTitleFontScale);
  }
  draw_legend(image, files, legend, kMarginTop + title_height);

  std::vector<const std::vector<double>*> all_x;
  for (const auto& file : files) all_x.push_back(&file.x);
  const Range x_range = padded_range(all_x, 0.0);
  const double x_step = tick_step(x_range, std::clamp(panel_width / 90, 2, 12));

  for (int panel = 0; panel < panels; ++panel) {
    std::vector<const std::vector<double>*> values;
    for (const auto& file : files) values.push_back(&file.columns[panel]);
    const Range y_range = padded_range(values, 0.06);
    const int top = header + panel * (panel_height + kPanelHeaderHeight + kPanelGap) + kPanelHeaderHeight;
    const cv::Rect area(kMarginLeft, top, panel_width, panel_height);
    draw_panel(image, area, options.columns[panel], x_range, x_step, y_range, panel == panels - 1, x_name);
    for (std::size_t i = 0; i < files.size(); ++i) {
      draw_series(image, files[i].x, files[i].columns[panel], x_range, y_range, area,
                  kLineColours[i % kLineColours.size()]);
    }
  }
  return image;
}

void run_plot(const PlotOptions& options) {
  std::unordered_set<std::string> seen;
  for (const auto& column : options.columns) {
    if (!seen.insert(column).second)
      throw CommandError(fmt::format("--columns: {} is given twice", column), kExitUsage);
  }
  std::vector<CsvTable> tables;
  for (const auto& file : options.files) tables.push_back(read_csv_table(file));
  const std::string x_name = x_column(tables);
  const std::vector<std::string> labels = legend_labels(options.files);
  std::vector<Trajectories> files;
  for (std::size_t i = 0; i < tables.size(); ++i) {
    files.push_back(read_trajectories(tables[i], x_name, options.columns, labels[i]));
  }

  const cv::Mat image = render_plot(files, options, x_name);
  try {
    write_png(options.out, image);
  } catch (const MediaError& e) {
    throw CommandError(e.what());
  }
  spdlog::info("wrote {} ({}x{})", options.out, image.cols, image.rows);
}

}  // namespace

void add_plot_command(CLI::App& app) {
  auto options = std::make_shared<PlotOptions>();
  CLI::App* plot =
      app.add_subcommand("plot", "Plot CSV columns over time (one panel per column, one line per file) to a PNG");
  plot->add_option("files", options->files, "Per-frame CSV files (lipdrive process, ground truth)")->required();
  plot->add_option("--columns", options->columns, "Columns to plot, comma-separated")->required()->delimiter(',');
  plot->add_option("--out", options->out, "Image file to write (.png)")->required();
  plot->add_option("--width", options->width, "Image width in pixels")
      ->capture_default_str()
      ->check(CLI::Range(300, kMaxImageSide));
  plot->add_option("--height", options->height, "Image height in pixels (default: 240 px per panel plus margins)")
      ->check(CLI::Range(150, kMaxImageSide));
  plot->add_option("--title", options->title, "Title above the plot");
  plot->callback([options, plot] {
    refuse_out_over_input(*plot);
    run_plot(*options);
  });
}

}  // namespace lipdrive
