/// \file
/// Checked private parameters for the nodes: each read names its key, type and range; a mistyped or out-of-range
/// value is refused with the reason (std::invalid_argument, so the node stops at start-up with a clear message
/// instead of running with a surprise), and keys nobody asked for (typos such as `~kp_gain`) are warned about.
#pragma once

#include <ros/node_handle.h>

#include <limits>
#include <set>
#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// Reads the parameters under one namespace (usually a node's private one) and remembers which keys were read.
class ParameterReader {
 public:
  /// `node`: the namespace read; `owner`: how messages name the reader (e.g. "bullet_sim").
  ParameterReader(const ros::NodeHandle& node, std::string owner);

  /// A number in [min, max] (an integer value is accepted too), `fallback` when the key is absent.
  /// \throws std::invalid_argument when the value is not a number or out of range.
  double number(const std::string& key, double fallback, double min = -std::numeric_limits<double>::infinity(),
                double max = std::numeric_limits<double>::infinity());
  /// An integer in [min, max].
  int integer(const std::string& key, int fallback, int min = std::numeric_limits<int>::min(),
              int max = std::numeric_limits<int>::max());
  bool boolean(const std::string& key, bool fallback);
  /// A string; when `choices` is not empty, one of them.
  std::string text(const std::string& key, const std::string& fallback, const std::vector<std::string>& choices = {});
  /// A list of `size` numbers in [min, max] (a single number is taken for every entry); `fallback` when absent.
  std::vector<double> numbers(const std::string& key, const std::vector<double>& fallback, std::size_t size,
                              double min = -std::numeric_limits<double>::infinity(),
                              double max = std::numeric_limits<double>::infinity());
  /// A list of strings.
  std::vector<std::string> texts(const std::string& key, const std::vector<std::string>& fallback);
  /// Whether the key is set (and marks it known).
  bool has(const std::string& key);
  /// Marks keys as known without reading them (e.g. read elsewhere, or a whole sub-namespace "name/").
  void accept(const std::string& key);

  /// Keys set under the namespace that no call asked for; each is also logged as a warning.
  std::vector<std::string> warnUnknown() const;
  /// The full name of a key, for messages ("/left/ctc_controller/kp").
  std::string name(const std::string& key) const;

 private:
  [[noreturn]] void refuse(const std::string& key, const std::string& why) const;

  ros::NodeHandle node_;
  std::string owner_;
  std::set<std::string> known_;
};

}  // namespace bimanual_skills::ros_layer
