#include "io/whole_file.hpp"

#include <cstdio>
#include <fstream>

namespace bimanual_skills::io {

bool writeWhole(const std::string& path, const std::function<void(std::ostream&)>& write) {
  const std::string part = path + ".part";
  {
    std::ofstream out(part);
    write(out);
    if (!out.flush()) {
      std::remove(part.c_str());
      return false;
    }
  }
  return std::rename(part.c_str(), path.c_str()) == 0;
}

}  // namespace bimanual_skills::io
