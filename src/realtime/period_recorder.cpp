#include "bimanual_skills/realtime/period_recorder.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace bimanual_skills::realtime {

double quantile(std::vector<double>& samples, double p) {
  if (samples.empty()) return 0.0;
  std::sort(samples.begin(), samples.end());
  const double rank = std::ceil(std::clamp(p, 0.0, 1.0) * static_cast<double>(samples.size()));
  const std::size_t index = rank < 1.0 ? 0 : static_cast<std::size_t>(rank) - 1;
  return samples[std::min(index, samples.size() - 1)];
}

PeriodSummary summarize(std::vector<double>& samples) {
  PeriodSummary s;
  s.count = samples.size();
  if (samples.empty()) return s;
  s.median = quantile(samples, 0.5);
  s.p99 = quantile(samples, 0.99);
  s.p999 = quantile(samples, 0.999);
  s.max = samples.back();
  s.mean = std::accumulate(samples.begin(), samples.end(), 0.0) / static_cast<double>(samples.size());
  return s;
}

PeriodRecorder::PeriodRecorder(std::size_t capacity) : ring_(new std::atomic<double>[capacity]), capacity_(capacity) {
  if (capacity == 0) throw std::invalid_argument("PeriodRecorder: capacity must be > 0");
  for (std::size_t i = 0; i < capacity; ++i) ring_[i].store(0.0, std::memory_order_relaxed);
}

void PeriodRecorder::record(double value) noexcept {
  const std::size_t n = written_.load(std::memory_order_relaxed);
  ring_[n % capacity_].store(value, std::memory_order_relaxed);
  written_.store(n + 1, std::memory_order_release);
}

void PeriodRecorder::snapshot(std::vector<double>& out) const {
  const std::size_t n = written_.load(std::memory_order_acquire);
  const std::size_t count = std::min(n, capacity_);
  out.resize(count);
  for (std::size_t k = 0; k < count; ++k) {
    out[k] = ring_[(n - count + k) % capacity_].load(std::memory_order_relaxed);
  }
}

void PeriodRecorder::writeCsv(std::ostream& out, const char* series) const {
  std::vector<double> samples;
  snapshot(samples);
  const std::streamsize precision = out.precision(17);
  for (double v : samples) out << series << ',' << v << '\n';
  out.precision(precision);
}

}  // namespace bimanual_skills::realtime
