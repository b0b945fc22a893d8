#include "bimanual_skills/ros_layer/parameters.hpp"

#include <ros/console.h>
#include <ros/param.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::ros_layer {

namespace {

bool isNumber(const XmlRpc::XmlRpcValue& v) {
  return v.getType() == XmlRpc::XmlRpcValue::TypeDouble || v.getType() == XmlRpc::XmlRpcValue::TypeInt;
}

double toNumber(XmlRpc::XmlRpcValue& v) {
  return v.getType() == XmlRpc::XmlRpcValue::TypeInt ? static_cast<double>(static_cast<int>(v))
                                                     : static_cast<double>(v);
}

std::string range(double min, double max) {
  std::ostringstream s;
  s << std::setprecision(12) << "[" << min << ", " << max << "]";
  return s.str();
}

}  // namespace

ParameterReader::ParameterReader(const ros::NodeHandle& node, std::string owner)
    : node_(node), owner_(std::move(owner)) {}

std::string ParameterReader::name(const std::string& key) const {
  return node_.resolveName(key);
}

void ParameterReader::refuse(const std::string& key, const std::string& why) const {
  throw std::invalid_argument("parameter " + name(key) + " " + why);
}

bool ParameterReader::has(const std::string& key) {
  known_.insert(key);
  return node_.hasParam(key);
}

void ParameterReader::accept(const std::string& key) {
  known_.insert(key);
}

double ParameterReader::number(const std::string& key, double fallback, double min, double max) {
  XmlRpc::XmlRpcValue v;
  if (!has(key) || !node_.getParam(key, v)) return fallback;
  if (!isNumber(v)) refuse(key, "must be a number");
  const double x = toNumber(v);
  if (!std::isfinite(x) || x < min || x > max) {
    std::ostringstream s;
    s << std::setprecision(12) << "= " << x << " is out of range " << range(min, max);
    refuse(key, s.str());
  }
  return x;
}

int ParameterReader::integer(const std::string& key, int fallback, int min, int max) {
  XmlRpc::XmlRpcValue v;
  if (!has(key) || !node_.getParam(key, v)) return fallback;
  if (v.getType() != XmlRpc::XmlRpcValue::TypeInt) refuse(key, "must be an integer");
  const int x = static_cast<int>(v);
  if (x < min || x > max) {
    refuse(key, "= " + std::to_string(x) + " is out of range " + range(min, max));
  }
  return x;
}

bool ParameterReader::boolean(const std::string& key, bool fallback) {
  XmlRpc::XmlRpcValue v;
  if (!has(key) || !node_.getParam(key, v)) return fallback;
  if (v.getType() != XmlRpc::XmlRpcValue::TypeBoolean) refuse(key, "must be true or false");
  return static_cast<bool>(v);
}

std::string ParameterReader::text(const std::string& key, const std::string& fallback,
                                  const std::vector<std::string>& choices) {
  XmlRpc::XmlRpcValue v;
  std::string x = fallback;
  if (has(key) && node_.getParam(key, v)) {
    if (v.getType() != XmlRpc::XmlRpcValue::TypeString) refuse(key, "must be a string");
    x = static_cast<std::string>(v);
  }
  if (!choices.empty() && std::find(choices.begin(), choices.end(), x) == choices.end()) {
    std::string list;
    for (const std::string& c : choices) list += (list.empty() ? "" : ", ") + c;
    refuse(key, "= '" + x + "' is not one of: " + list);
  }
  return x;
}

std::vector<double> ParameterReader::numbers(const std::string& key, const std::vector<double>& fallback,
                                             std::size_t size, double min, double max) {
  XmlRpc::XmlRpcValue v;
  if (!has(key) || !node_.getParam(key, v)) return fallback;
  std::vector<double> x;
  if (isNumber(v)) {
    x.assign(size, toNumber(v));
  } else if (v.getType() == XmlRpc::XmlRpcValue::TypeArray) {
    for (int i = 0; i < v.size(); ++i) {
      if (!isNumber(v[i])) refuse(key, "must be a list of numbers (entry " + std::to_string(i) + " is not)");
      x.push_back(toNumber(v[i]));
    }
  } else {
    refuse(key, "must be a number or a list of " + std::to_string(size) + " numbers");
  }
  if (x.size() != size) {
    refuse(key, "has " + std::to_string(x.size()) + " entries; it needs " + std::to_string(size));
  }
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || x[i] < min || x[i] > max) {
      std::ostringstream s;
      s << "entry " << i << " = " << x[i] << " is out of range " << range(min, max);
      refuse(key, s.str());
    }
  }
  return x;
}

std::vector<std::string> ParameterReader::texts(const std::string& key, const std::vector<std::string>& fallback) {
  XmlRpc::XmlRpcValue v;
  if (!has(key) || !node_.getParam(key, v)) return fallback;
  if (v.getType() != XmlRpc::XmlRpcValue::TypeArray) refuse(key, "must be a list of strings");
  std::vector<std::string> x;
  for (int i = 0; i < v.size(); ++i) {
    if (v[i].getType() != XmlRpc::XmlRpcValue::TypeString) {
      refuse(key, "must be a list of strings (entry " + std::to_string(i) + " is not)");
    }
    x.push_back(static_cast<std::string>(v[i]));
  }
  return x;
}

std::vector<std::string> ParameterReader::warnUnknown() const {
  std::vector<std::string> all, unknown;
  if (!ros::param::getParamNames(all)) return unknown;
  const std::string prefix = node_.getNamespace() == "/" ? "/" : node_.getNamespace() + "/";
  for (const std::string& full : all) {
    if (full.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string key = full.substr(prefix.size());
    const bool known = std::any_of(known_.begin(), known_.end(), [&key](const std::string& k) {
      return key == k || (!k.empty() && k.back() == '/' && key.compare(0, k.size(), k) == 0) ||
             key.compare(0, k.size() + 1, k + "/") == 0;
    });
    if (!known) {
      unknown.push_back(key);
      ROS_WARN("%s: unknown parameter %s (ignored; a typo?)", owner_.c_str(), full.c_str());
    }
  }
  return unknown;
}

}  // namespace bimanual_skills::ros_layer
