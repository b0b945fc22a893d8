/// \file
/// Where a program finds the package's files (URDFs, configurations, plot scripts): the share directory beside the
/// program, `<prefix>/lib/bimanual_skills/PROGRAM` → `<prefix>/share/bimanual_skills/`, in the install space as in
/// the build tree (whose share directory links the source folders), so an installed program never needs the source
/// tree. Programs only.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace bimanual_skills::cli {

/// The package's share directory (it holds config/, urdf/, launch/ and scripts/).
/// \throws std::runtime_error naming where it looked.
inline std::string packageShare() {
  namespace fs = std::filesystem;
  std::error_code error;
  const fs::path exe = fs::read_symlink("/proc/self/exe", error);
  if (!error) {
    const fs::path share = exe.parent_path().parent_path().parent_path() / "share" / "bimanual_skills";
    if (fs::exists(share / "config" / "sim.yaml")) return share.string();
  }
  throw std::runtime_error("cannot find the bimanual_skills share directory beside " + exe.string() +
                           " (expected <prefix>/share/bimanual_skills next to <prefix>/lib/bimanual_skills)");
}

/// A file of the share directory, e.g. packageFile("urdf/wam.urdf").
inline std::string packageFile(const std::string& relative) {
  return packageShare() + "/" + relative;
}

}  // namespace bimanual_skills::cli
