/// \file
/// The command line of the project's programs: `--flag value` options and `--switch` flags declared with a help
/// line each; `--help` or `-h` prints the usage on stdout and exits 0; an unknown argument, a missing or malformed
/// value (or one outside an option's choices) prints the error and the usage on stderr and exits 2. Programs only (not
/// installed).
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

namespace bimanual_skills::cli {

/// The items with `separator` between them ("a|b|c" for the choices of an option).
inline std::string joined(const std::vector<std::string>& items, const std::string& separator) {
  std::string text;
  for (std::size_t i = 0; i < items.size(); ++i) text += (i > 0 ? separator : "") + items[i];
  return text;
}

class CommandLine {
 public:
  /// `synopsis`: the arguments after the program name; `description`: what the program does (any lines).
  CommandLine(std::string program, std::string synopsis, std::string description)
      : program_(std::move(program)), synopsis_(std::move(synopsis)), description_(std::move(description)) {}

  /// An option with a string value.
  void option(const std::string& flag, const std::string& value_name, const std::string& help, std::string* target) {
    add(flag, value_name, help, [target](const std::string& text) {
      *target = text;
      return true;
    });
  }
  /// An option with a finite number.
  void option(const std::string& flag, const std::string& value_name, const std::string& help, double* target) {
    add(flag, value_name, help, [target](const std::string& text) {
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (text.empty() || *end != '\0' || !(v == v) || v > std::numeric_limits<double>::max() ||
          v < -std::numeric_limits<double>::max()) {
        return false;
      }
      *target = v;
      return true;
    });
  }
  /// An option with an integer in [minimum, maximum].
  void option(const std::string& flag, const std::string& value_name, const std::string& help, long* target,
              long minimum, long maximum) {
    add(flag, value_name, help, [target, minimum, maximum](const std::string& text) {
      char* end = nullptr;
      const long v = std::strtol(text.c_str(), &end, 10);
      if (text.empty() || *end != '\0' || v < minimum || v > maximum) return false;
      *target = v;
      return true;
    });
  }
  /// An option whose value is one of `choices` (the usage shows them as its value, a|b|c).
  void choice(const std::string& flag, const std::vector<std::string>& choices, const std::string& help,
              std::string* target) {
    const std::string names = joined(choices, "|");
    add(
        flag, names, help,
        [target, choices](const std::string& text) {
          if (std::find(choices.begin(), choices.end(), text) == choices.end()) return false;
          *target = text;
          return true;
        },
        "one of " + names);
  }
  /// A switch without a value.
  void flag(const std::string& flag, const std::string& help, bool* target) {
    add(flag, "", help, [target](const std::string&) {
      *target = true;
      return true;
    });
  }

  /// Parses argv (see the file comment). Does not return on --help or an error.
  void parse(int argc, char** argv) const {
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg == "--help" || arg == "-h") {
        std::cout << usage();
        std::exit(0);
      }
      const Option* match = nullptr;
      for (const Option& o : options_) {
        if (o.flag == arg) match = &o;
      }
      if (match == nullptr) fail("unknown argument '" + arg + "'");
      std::string value;
      if (!match->value_name.empty()) {
        if (i + 1 >= argc) fail(arg + " needs a value " + match->value_name);
        value = argv[++i];
      }
      if (!match->set(value)) fail(arg + ": '" + value + "' is not " + match->expected);
    }
  }

  /// Prints the error and the usage on stderr and exits 2.
  [[noreturn]] void fail(const std::string& error) const {
    std::cerr << program_ << ": " << error << "\n" << usage();
    std::exit(2);
  }

  std::string usage() const {
    std::string text = "usage: " + program_ + " " + synopsis_ + "\n\n" + description_ + "\n\noptions:\n";
    for (const Option& o : options_) {
      std::string left = "  " + o.flag + (o.value_name.empty() ? "" : " " + o.value_name);
      left.resize(std::max<std::size_t>(left.size() + 2, 26), ' ');
      text += left + o.help + "\n";
    }
    text += "  -h, --help              print this help and exit\n";
    return text;
  }

 private:
  struct Option {
    std::string flag, value_name, help;
    std::function<bool(const std::string&)> set;
    std::string expected;  ///< What a rejected value is not ("a valid N", "one of a|b").
  };
  /// `expected`: what a rejected value is not (default "a valid " + value_name).
  void add(const std::string& flag, const std::string& value_name, const std::string& help,
           std::function<bool(const std::string&)> set, const std::string& expected = "") {
    options_.push_back({flag, value_name, help, std::move(set), expected.empty() ? "a valid " + value_name : expected});
  }

  std::string program_, synopsis_, description_;
  std::vector<Option> options_;
};

}  // namespace bimanual_skills::cli
