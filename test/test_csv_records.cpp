// io::CsvAppender and io::dropPartialRecord: whole records, a partial last line cut off on reopening; the fields of a
// record: quoted text with commas and quotes, numbers read back bit for bit, bad numbers refused; io::writeWhole.
#include "io/csv_records.hpp"
#include "io/whole_file.hpp"
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>

namespace fs = std::filesystem;
using bimanual_skills::testing::readTextFile;

TEST(CsvRecords, AppendsWholeRecordsAndDropsAPartialLastLine) {
  const std::string path = (fs::temp_directory_path() / "bimanual_skills_csv_records.csv").string();
  fs::remove(path);
  EXPECT_EQ(bimanual_skills::io::dropPartialRecord(path), 0u);  // no file
  {
    bimanual_skills::io::CsvAppender csv(path, "a,b");
    csv.append("1,2");
    csv.append("3,4");
  }
  EXPECT_EQ(readTextFile(path), "a,b\n1,2\n3,4\n");
  std::ofstream(path, std::ios::app) << "5,";  // killed in the middle of a record
  {
    bimanual_skills::io::CsvAppender csv(path, "a,b");  // the header is not written again
    csv.append("5,6");
  }
  EXPECT_EQ(readTextFile(path), "a,b\n1,2\n3,4\n5,6\n");
  std::ofstream(path, std::ios::app) << "7,8,9,10,11";
  EXPECT_EQ(bimanual_skills::io::dropPartialRecord(path), 11u);
  EXPECT_EQ(bimanual_skills::io::dropPartialRecord(path), 0u);
  std::ofstream(path, std::ios::trunc) << "no newline at all";
  EXPECT_EQ(bimanual_skills::io::dropPartialRecord(path), 17u);
  EXPECT_EQ(fs::file_size(path), 0u);
  fs::remove(path);
}

TEST(CsvRecords, FieldsRoundTrip) {
  namespace io = bimanual_skills::io;
  const std::string reason = "arm 0 is \"far\", off by 0.3 rad\nat t = 1 s";
  const std::vector<std::string> fields =
      io::splitCsv("IDR,1," + io::quotedField(reason) + ",," + io::exactNumber(0.1 + 0.2));
  ASSERT_EQ(fields.size(), 5u);
  EXPECT_EQ(fields[2], "arm 0 is \"far\", off by 0.3 rad at t = 1 s");
  EXPECT_EQ(fields[3], "");
  EXPECT_EQ(io::parseNumber(fields[4], "here"), 0.1 + 0.2);  // bit for bit
  for (const double v : {-1e-300, 6.02214076e23, std::numeric_limits<double>::denorm_min()}) {
    EXPECT_EQ(io::parseNumber(io::exactNumber(v), "here"), v);
  }
  EXPECT_EQ(io::parseInteger("42", "here"), 42);
  for (const char* bad : {"", "1.5x", "x", " 1"}) {
    EXPECT_THROW(io::parseNumber(bad, "here"), std::invalid_argument) << bad;
  }
  EXPECT_THROW(io::parseInteger("1.5", "here"), std::invalid_argument);
  EXPECT_THROW(io::parseInteger("1e12", "here"), std::invalid_argument);
}

TEST(WholeFile, ReplacesTheFileOrLeavesTheOldOne) {
  const std::string path = (fs::temp_directory_path() / "bimanual_skills_whole_file.csv").string();
  fs::remove(path);
  ASSERT_TRUE(bimanual_skills::io::writeWhole(path, [](std::ostream& out) { out << "a,b\n1,2\n"; }));
  EXPECT_EQ(readTextFile(path), "a,b\n1,2\n");
  EXPECT_FALSE(fs::exists(path + ".part"));
  // A writer that fails half-way (here: the stream set bad after a partial record) leaves the old file whole.
  EXPECT_FALSE(bimanual_skills::io::writeWhole(path, [](std::ostream& out) {
    out << "a,b\n3,";
    out.setstate(std::ios::badbit);
  }));
  EXPECT_EQ(readTextFile(path), "a,b\n1,2\n");
  EXPECT_FALSE(fs::exists(path + ".part"));
  // A directory that does not exist: refused, nothing written.
  const std::string nowhere = (fs::temp_directory_path() / "bimanual_skills_no_such_dir" / "x.csv").string();
  EXPECT_FALSE(bimanual_skills::io::writeWhole(nowhere, [](std::ostream& out) { out << "x\n"; }));
  EXPECT_FALSE(fs::exists(nowhere));
  // A writer that throws: passed on, the old file whole, nothing left beside it.
  EXPECT_THROW(bimanual_skills::io::writeWhole(path,
                                               [](std::ostream& out) {
                                                 out << "a,b\n4,";
                                                 throw std::runtime_error("no");
                                               }),
               std::runtime_error);
  EXPECT_EQ(readTextFile(path), "a,b\n1,2\n");
  EXPECT_FALSE(fs::exists(path + ".part"));
  // A path that names a directory: the rename fails, nothing left beside it.
  const fs::path directory = fs::temp_directory_path() / "bimanual_skills_whole_file_dir";
  fs::create_directories(directory / "inside");
  EXPECT_FALSE(bimanual_skills::io::writeWhole(directory.string(), [](std::ostream& out) { out << "x\n"; }));
  EXPECT_FALSE(fs::exists(directory.string() + ".part"));
  fs::remove_all(directory);
  fs::remove(path);
}
