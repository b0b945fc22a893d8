// io::CsvAppender and io::dropPartialRecord: whole records, a partial last line cut off on reopening.
#include "io/csv_records.hpp"
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

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
