#include "bimanual_skills/vision/image_reward.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace bimanual_skills::vision {

namespace {

[[noreturn]] void fail(const char* where, const std::string& what) {
  throw std::invalid_argument(std::string(where) + ": " + what);
}

bool nonNegative(double x) {
  return std::isfinite(x) && x >= 0.0;
}

}  // namespace

void ImageRewardParameters::validate(const char* where) const {
  const ClothSegmentation& s = segmentation;
  if (s.hue_min < 0 || s.hue_max > 179 || s.hue_min > s.hue_max) {
    fail(where, "segmentation hue range must satisfy 0 <= hue_min <= hue_max <= 179");
  }
  if (s.saturation_min < 0 || s.saturation_min > 255 || s.value_min < 0 || s.value_min > 255) {
    fail(where, "segmentation saturation_min and value_min must be in [0, 255]");
  }
  if (!nonNegative(colour_weight) || !nonNegative(depth_weight)) fail(where, "weights must be finite and >= 0");
  if (border_erosion < 0 || border_erosion > 100) fail(where, "border_erosion must be in [0, 100]");
  if (!nonNegative(depth_smoothing)) fail(where, "depth_smoothing must be finite and >= 0");
  if (!nonNegative(no_cloth_gradient)) fail(where, "no_cloth_gradient must be finite and >= 0");
  if (!nonNegative(goal_weight)) fail(where, "goal_weight must be finite and >= 0");
  if (!(std::isfinite(goal_missing_height) && goal_missing_height > 0.0 && std::isfinite(goal_excess_height) &&
        goal_excess_height > 0.0)) {
    fail(where, "goal_missing_height and goal_excess_height must be finite and > 0");
  }
  if (!nonNegative(fold_weight) || !nonNegative(fold_edge_weight) || !nonNegative(fold_single_weight) ||
      !nonNegative(fold_length_weight) || !(fold_single_weight + fold_length_weight > 0.0)) {
    fail(where, "fold weights must be finite and >= 0, fold_single_weight + fold_length_weight > 0");
  }
  if (!(std::isfinite(layer_threshold) && layer_threshold > 1.0)) fail(where, "layer_threshold must be > 1");
  if (!nonNegative(fold_smoothing)) fail(where, "fold_smoothing must be finite and >= 0");
  if (!nonNegative(fold_heap_weight)) fail(where, "fold_heap_weight must be finite and >= 0");
  if (!(std::isfinite(heap_threshold) && heap_threshold > layer_threshold)) {
    fail(where, "heap_threshold must be finite and > layer_threshold");
  }
  if (!(std::isfinite(heap_reach) && heap_reach > 0.0 && heap_reach <= 1.0))
    fail(where, "heap_reach must be in (0, 1]");
}

ImageReward::ImageReward(const TopDownCamera& camera, const ImageRewardParameters& parameters)
    : camera_(camera), parameters_(parameters) {
  camera_.validate("ImageReward");
  parameters_.validate("ImageReward");
  const int rows = camera_.rows, columns = camera_.columns;
  hsv_.create(rows, columns, CV_8UC3);
  mask_.create(rows, columns, CV_8UC1);
  opened_.create(rows, columns, CV_8UC1);
  eroded_.create(rows, columns, CV_8UC1);
  weights_.create(rows, columns, CV_32FC1);
  weighted_.create(rows, columns, CV_32FC1);
  smoothed_.create(rows, columns, CV_32FC1);
  gx_.create(rows, columns, CV_32FC1);
  gy_.create(rows, columns, CV_32FC1);
  height_.create(rows, columns, CV_32FC1);
  smoothed_height_.create(rows, columns, CV_32FC1);
  points_.reserve(4 * static_cast<std::size_t>(rows + columns));
  mask_.setTo(0);
}

bool ImageReward::fits(const cv::Mat& image, int type) const noexcept {
  return !image.empty() && image.type() == type && image.rows == camera_.rows && image.cols == camera_.columns &&
         image.dims == 2;
}

VisionStatus ImageReward::segment(const cv::Mat& bgr) {
  if (!fits(bgr, CV_8UC3)) {
    mask_.setTo(0);
    return VisionStatus::WrongImageSize;
  }
  const ClothSegmentation& s = parameters_.segmentation;
  cv::cvtColor(bgr, hsv_, cv::COLOR_BGR2HSV);
  cv::inRange(hsv_, cv::Scalar(s.hue_min, s.saturation_min, s.value_min), cv::Scalar(s.hue_max, 255, 255), mask_);
  if (s.remove_speckles) {
    cv::morphologyEx(mask_, opened_, cv::MORPH_OPEN, cv::Mat());
    std::swap(mask_, opened_);
  }
  return cv::countNonZero(mask_) > 0 ? VisionStatus::Ok : VisionStatus::NoCloth;
}

ColourTerm ImageReward::colourTerm(const cv::Mat& mask) {
  ColourTerm term;
  if (!fits(mask, CV_8UC1)) {
    term.status = VisionStatus::WrongImageSize;
    return term;
  }
  term.cloth_pixels = cv::countNonZero(mask);
  if (term.cloth_pixels == 0) return term;  // NoCloth, ρ = 0.
  // The convex hull of the pixel centres is that of the outer contours' points: fit the rectangle to those only.
  cv::findContours(mask, contours_, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  points_.clear();
  for (const std::vector<cv::Point>& contour : contours_) points_.insert(points_.end(), contour.begin(), contour.end());
  term.rectangle = cv::minAreaRect(points_);
  // The rectangle passes through pixel centres: each side gains one pixel of extent.
  const double area = (double(term.rectangle.size.width) + 1.0) * (double(term.rectangle.size.height) + 1.0);
  term.fill_ratio = std::min(1.0, term.cloth_pixels / area);
  term.status = VisionStatus::Ok;
  return term;
}

DepthTerm ImageReward::depthTerm(const cv::Mat& depth, const cv::Mat& mask) {
  DepthTerm term;
  if (!fits(depth, CV_32FC1) || !fits(mask, CV_8UC1)) {
    term.status = VisionStatus::WrongImageSize;
    return term;
  }
  if (cv::countNonZero(mask) == 0) return term;  // NoCloth.
  const cv::Mat* source = &depth;
  if (parameters_.depth_smoothing > 0.0) {
    // Normalised convolution over the cloth: blur(d·m) / blur(m), the raw depth where no cloth is near.
    for (int v = 0; v < camera_.rows; ++v) {
      const unsigned char* m = mask.ptr<unsigned char>(v);
      const float* d = depth.ptr<float>(v);
      float* w = weights_.ptr<float>(v);
      float* wd = weighted_.ptr<float>(v);
      for (int u = 0; u < camera_.columns; ++u) {
        const bool use = m[u] != 0 && std::isfinite(d[u]);
        w[u] = use ? 1.0f : 0.0f;
        wd[u] = use ? d[u] : 0.0f;
      }
    }
    const double sigma = parameters_.depth_smoothing / camera_.pixel_size;
    cv::GaussianBlur(weights_, weights_, cv::Size(0, 0), sigma, sigma, cv::BORDER_CONSTANT);
    cv::GaussianBlur(weighted_, weighted_, cv::Size(0, 0), sigma, sigma, cv::BORDER_CONSTANT);
    for (int v = 0; v < camera_.rows; ++v) {
      const float* d = depth.ptr<float>(v);
      const float* w = weights_.ptr<float>(v);
      const float* wd = weighted_.ptr<float>(v);
      float* out = smoothed_.ptr<float>(v);
      for (int u = 0; u < camera_.columns; ++u) out[u] = w[u] > 1e-3f ? wd[u] / w[u] : d[u];
    }
    source = &smoothed_;
  }
  // Sobel 3 × 3: [−1 0 1; −2 0 2; −1 0 1] is 8 s times ∂d/∂x for pixels of side s.
  const double scale = 1.0 / (8.0 * camera_.pixel_size);
  cv::Sobel(*source, gx_, CV_32F, 1, 0, 3, scale, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(*source, gy_, CV_32F, 0, 1, 3, scale, 0.0, cv::BORDER_REPLICATE);

  const cv::Mat* region = &mask;
  if (parameters_.border_erosion > 0) {
    cv::erode(mask, eroded_, cv::Mat(), cv::Point(-1, -1), parameters_.border_erosion, cv::BORDER_CONSTANT,
              cv::Scalar(0));
    if (cv::countNonZero(eroded_) > 0) region = &eroded_;
  }
  double sum = 0.0;
  int count = 0;
  for (int v = 0; v < camera_.rows; ++v) {
    const unsigned char* m = region->ptr<unsigned char>(v);
    const float* d = depth.ptr<float>(v);
    const float* gx = gx_.ptr<float>(v);
    const float* gy = gy_.ptr<float>(v);
    for (int u = 0; u < camera_.columns; ++u) {
      if (m[u] == 0 || !std::isfinite(d[u])) continue;
      const double g = std::sqrt(double(gx[u]) * gx[u] + double(gy[u]) * gy[u]);
      if (!std::isfinite(g)) continue;
      sum += g;
      ++count;
    }
  }
  term.pixels = count;
  if (count == 0) return term;  // Every cloth pixel had a non-finite depth: nothing seen.
  term.mean_gradient = sum / count;
  term.status = VisionStatus::Ok;
  return term;
}

void ImageReward::setGoal(const cv::Mat& mask, const cv::Mat& depth) {
  if (!fits(mask, CV_8UC1) || !fits(depth, CV_32FC1)) {
    fail("ImageReward::setGoal", "a CV_8UC1 mask and a CV_32FC1 depth image of the camera's size are needed");
  }
  if (cv::countNonZero(mask) == 0) fail("ImageReward::setGoal", "the goal mask has no cloth");
  for (int v = 0; v < camera_.rows; ++v) {
    const unsigned char* m = mask.ptr<unsigned char>(v);
    const float* d = depth.ptr<float>(v);
    for (int u = 0; u < camera_.columns; ++u) {
      if (m[u] != 0 && !std::isfinite(d[u])) fail("ImageReward::setGoal", "the goal depth is not finite on the cloth");
    }
  }
  mask.copyTo(goal_mask_);
  depth.copyTo(goal_depth_);
  has_goal_ = true;
}

GoalTerm ImageReward::goalTerm(const cv::Mat& depth, const cv::Mat& mask) const {
  GoalTerm term;
  if (!fits(depth, CV_32FC1) || !fits(mask, CV_8UC1)) {
    term.status = VisionStatus::WrongImageSize;
    return term;
  }
  if (!has_goal_ || cv::countNonZero(mask) == 0) return term;  // NoCloth: the worst values.
  const double missing = parameters_.goal_missing_height, excess = parameters_.goal_excess_height;
  double error = 0.0;
  int shared = 0, either = 0;
  for (int v = 0; v < camera_.rows; ++v) {
    const unsigned char* m = mask.ptr<unsigned char>(v);
    const unsigned char* g = goal_mask_.ptr<unsigned char>(v);
    const float* d = depth.ptr<float>(v);
    const float* dg = goal_depth_.ptr<float>(v);
    for (int u = 0; u < camera_.columns; ++u) {
      const bool seen = m[u] != 0, goal = g[u] != 0;
      if (!seen && !goal) continue;
      ++either;
      if (seen && goal) {
        ++shared;
        const double above = double(dg[u]) - double(d[u]);
        const double e = std::max(-above / missing, above / excess);
        error += std::isfinite(e) ? std::min(e, 1.0) : 1.0;
      } else {
        error += 1.0;
      }
    }
  }
  term.iou = double(shared) / either;
  term.mismatch = error / either;
  term.status = VisionStatus::Ok;
  return term;
}

namespace {

/// The median of `values` (not empty); reorders them.
double median(std::vector<float>& values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

}  // namespace

void ImageReward::setFlat(const cv::Mat& bgr, const cv::Mat& depth) {
  const char* const where = "ImageReward::setFlat";
  if (!fits(bgr, CV_8UC3) || !fits(depth, CV_32FC1)) {
    fail(where, "a CV_8UC3 colour and a CV_32FC1 depth image of the camera's size are needed");
  }
  if (segment(bgr) != VisionStatus::Ok) fail(where, "no cloth in the flat cloth's image");
  // The table: a band from 1 to 4 cm around the cloth.
  const auto pixels = [&](double metres) {
    return std::max(1, static_cast<int>(std::lround(metres / camera_.pixel_size)));
  };
  cv::Mat outer, inner;
  cv::dilate(mask_, outer, cv::Mat(), cv::Point(-1, -1), pixels(0.04));
  cv::dilate(mask_, inner, cv::Mat(), cv::Point(-1, -1), pixels(0.01));
  cv::erode(mask_, eroded_, cv::Mat(), cv::Point(-1, -1), 2, cv::BORDER_CONSTANT, cv::Scalar(0));
  std::vector<float> table, cloth;
  FlatCloth flat;
  flat.near_column = camera_.columns;
  flat.first_row = camera_.rows;
  flat.far_column = flat.last_row = -1;
  for (int v = 0; v < camera_.rows; ++v) {
    const unsigned char* m = mask_.ptr<unsigned char>(v);
    const unsigned char* o = outer.ptr<unsigned char>(v);
    const unsigned char* i = inner.ptr<unsigned char>(v);
    const unsigned char* e = eroded_.ptr<unsigned char>(v);
    const float* d = depth.ptr<float>(v);
    for (int u = 0; u < camera_.columns; ++u) {
      if (m[u] != 0) {
        flat.near_column = std::min(flat.near_column, u);
        flat.far_column = std::max(flat.far_column, u + 1);
        flat.first_row = std::min(flat.first_row, v);
        flat.last_row = std::max(flat.last_row, v);
      }
      if (!std::isfinite(d[u])) continue;
      if (o[u] != 0 && i[u] == 0) table.push_back(d[u]);
      if (e[u] != 0) cloth.push_back(d[u]);
    }
  }
  if (table.empty()) fail(where, "no table around the flat cloth");
  if (cloth.empty()) fail(where, "the flat cloth has no pixel of finite depth away from its edge");
  flat.table_depth = median(table);
  flat.thickness = flat.table_depth - median(cloth);
  if (!(flat.thickness > 0.0)) fail(where, "the flat cloth is not above the table");
  if (flat.far_column - flat.near_column < 2) fail(where, "the flat cloth is narrower than two pixels");
  flat_ = flat;
  has_flat_ = true;
}

FoldTerm ImageReward::foldTerm(const cv::Mat& depth, const cv::Mat& mask) {
  FoldTerm term;
  if (!fits(depth, CV_32FC1) || !fits(mask, CV_8UC1)) {
    term.status = VisionStatus::WrongImageSize;
    return term;
  }
  if (!has_flat_) return term;  // NoCloth: mismatch 1.
  const ImageRewardParameters& p = parameters_;
  const double s = camera_.pixel_size, uc = flat_.fold_column();
  const int u0 = flat_.near_column, u1 = flat_.far_column, goal_end = static_cast<int>(std::ceil(uc));
  const double flat_error = p.fold_single_weight * (uc - u0) * s + p.fold_length_weight * (u1 - uc) * s;
  term.mismatch = 2.0;
  if (cv::countNonZero(mask) == 0) return term;  // NoCloth: worse than the flat cloth.
  // Height above the table on the cloth, smoothed.
  for (int v = 0; v < camera_.rows; ++v) {
    const unsigned char* m = mask.ptr<unsigned char>(v);
    const float* d = depth.ptr<float>(v);
    float* h = height_.ptr<float>(v);
    for (int u = 0; u < camera_.columns; ++u) {
      const double above = flat_.table_depth - double(d[u]);
      h[u] = m[u] != 0 && std::isfinite(above) ? static_cast<float>(std::max(0.0, above)) : 0.0f;
    }
  }
  const cv::Mat* height = &height_;
  if (p.fold_smoothing > 0.0) {
    const double sigma = p.fold_smoothing / s;
    cv::GaussianBlur(height_, smoothed_height_, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
    height = &smoothed_height_;
  }
  const double layer = p.layer_threshold * flat_.thickness, heap_height = p.heap_threshold * flat_.thickness;
  const double heap_end = u0 + p.heap_reach * (uc - u0);
  double edge = 0.0, single = 0.0, length = 0.0, heap = 0.0, empty = 0.0;
  for (int v = flat_.first_row; v <= flat_.last_row; ++v) {
    const unsigned char* m = mask.ptr<unsigned char>(v);
    const float* h = height->ptr<float>(v);
    int a = -1, b = -1, thin = 0, heaped = 0;
    for (int u = 0; u < camera_.columns; ++u) {
      if (m[u] == 0) continue;
      if (a < 0) a = u;
      b = u + 1;
      if (u >= u0 && u < goal_end && h[u] < layer) ++thin;
      if (u >= u0 && u < heap_end && h[u] > heap_height) ++heaped;
    }
    if (a < 0) {
      empty += 1.0;
      continue;
    }
    edge += std::abs(a - u0) * s;
    single += thin * s;
    length += std::abs((b - a) - (uc - u0)) * s;
    heap += heaped * s;
  }
  const double rows = flat_.last_row - flat_.first_row + 1;
  term.edge = edge / rows;
  term.single = single / rows;
  term.length = length / rows;
  term.heap = heap / rows;
  term.error = p.fold_edge_weight * term.edge + p.fold_single_weight * term.single +
               p.fold_length_weight * term.length + p.fold_heap_weight * term.heap + 2.0 * flat_error * empty / rows;
  term.mismatch = term.error / flat_error;
  term.status = VisionStatus::Ok;
  return term;
}

FoldFacts ImageReward::foldFacts(const cv::Mat& mask, double flat_area) {
  if (!(std::isfinite(flat_area) && flat_area > 0.0)) {
    throw std::invalid_argument("ImageReward::foldFacts: flat_area must be finite and > 0");
  }
  FoldFacts facts;
  const ColourTerm colour = colourTerm(mask);
  facts.status = colour.status;
  if (colour.status != VisionStatus::Ok) return facts;
  const double s = camera_.pixel_size;
  facts.cloth_pixels = colour.cloth_pixels;
  facts.cloth_area = colour.cloth_pixels * camera_.pixelArea();
  facts.area_ratio = facts.cloth_area / flat_area;
  const double a = (colour.rectangle.size.width + 1.0) * s;
  const double b = (colour.rectangle.size.height + 1.0) * s;
  facts.rectangle_length = std::max(a, b);
  facts.rectangle_width = std::min(a, b);
  facts.aspect = facts.rectangle_length / facts.rectangle_width;
  facts.fill_ratio = colour.fill_ratio;
  return facts;
}

ImageRewardTerms ImageReward::evaluate(const cv::Mat& bgr, const cv::Mat& depth) {
  ImageRewardTerms terms;
  const VisionStatus segmented = segment(bgr);
  if (segmented == VisionStatus::WrongImageSize || !fits(depth, CV_32FC1)) {
    terms.status = VisionStatus::WrongImageSize;
  } else {
    terms.colour = colourTerm(mask_);
    terms.depth = depthTerm(depth, mask_);
    terms.goal = goalTerm(depth, mask_);
    terms.fold = foldTerm(depth, mask_);
    terms.status = terms.colour.status != VisionStatus::Ok ? terms.colour.status : terms.depth.status;
  }
  const bool seen = terms.status == VisionStatus::Ok;
  terms.r_color = parameters_.colour_weight * (seen ? 1.0 - terms.colour.fill_ratio : 1.0);
  terms.r_depth = parameters_.depth_weight * (seen ? terms.depth.mean_gradient : parameters_.no_cloth_gradient);
  terms.r_goal = parameters_.goal_weight * (seen && terms.goal.status == VisionStatus::Ok ? terms.goal.mismatch : 1.0);
  // Without a flat cloth the fold term is unknown (1); without cloth in view, worse than the flat cloth (2).
  terms.r_fold = parameters_.fold_weight * (!has_flat_ ? 1.0 : seen ? terms.fold.mismatch : 2.0);
  return terms;
}

}  // namespace bimanual_skills::vision
