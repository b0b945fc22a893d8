#include "io/whole_file.hpp"

#include <cstdio>
#include <fstream>

namespace bimanual_skills::io {

bool writeWhole(const std::string& path, const std::function<void(std::ostream&)>& write) {
  const std::string part = path + ".part";
  bool written = false;
  try {
    std::ofstream out(part);
    write(out);
    out.close();
    written = !out.fail();
  } catch (...) {
    std::remove(part.c_str());
    throw;
  }
  if (written && std::rename(part.c_str(), path.c_str()) == 0) return true;
  std::remove(part.c_str());
  return false;
}

}  // namespace bimanual_skills::io
