// scripts/check_results.py: RESULTS' summary rows and README's marked paragraphs say what their sections measured. It
// passes on the repository's docs, fails when a number is changed in a summary row or a marked README paragraph only,
// and passes again when the section says the same.
#include "testing/program_output.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

namespace fs = std::filesystem;

namespace {

const std::string kSource = BIMANUAL_SKILLS_SOURCE_DIR;

/// A copy of the repository's two documents (what the script reads) in a fresh directory.
fs::path copyDocs(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("bimanual_skills_results_check_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir / "docs");
  fs::copy_file(kSource + "/README.md", dir / "README.md");
  fs::copy_file(kSource + "/docs/RESULTS.md", dir / "docs" / "RESULTS.md");
  return dir;
}

void write(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

int check(const fs::path& repo) {
  return bimanual_skills::testing::runQuietly("/usr/bin/python3 " + kSource + "/scripts/check_results.py " +
                                              repo.string());
}

/// The first decimal of the "Our figure" cell of the first row of RESULTS' Summary table, and that row's text.
std::pair<std::string, std::string> firstSummaryNumber(const std::string& results) {
  const std::size_t table = results.find("## Summary");
  std::size_t row = results.find("\n| ", results.find("|---", table));
  const std::string line = results.substr(row + 1, results.find('\n', row + 1) - row - 1);
  const std::size_t figure = line.find('|', 1);
  std::smatch m;
  const std::string rest = line.substr(figure);
  EXPECT_TRUE(std::regex_search(rest, m, std::regex(R"(\d+\.\d+)")));
  return {m.str(), line};
}

}  // namespace

TEST(ResultsCheck, TheRepositorysDocsAgreeWithTheirSections) {
  EXPECT_EQ(check(kSource), 0) << "run scripts/check_results.py: a summary says what its section does not";
}

TEST(ResultsCheck, ANumberChangedInTheSummaryOnlyFailsAndInBothPasses) {
  const fs::path repo = copyDocs("summary");
  const std::string results = bimanual_skills::testing::readTextFile((repo / "docs" / "RESULTS.md").string());
  const auto [number, row] = firstSummaryNumber(results);
  ASSERT_FALSE(number.empty());
  const std::string changed = "987.654";
  ASSERT_EQ(results.find(changed), std::string::npos);
  // In the summary row only.
  std::string row_changed = row;
  row_changed.replace(row_changed.find(number), number.size(), changed);
  std::string text = results;
  text.replace(text.find(row), row.size(), row_changed);
  write(repo / "docs" / "RESULTS.md", text);
  EXPECT_NE(check(repo), 0) << number << " changed to " << changed << " in the summary only";
  // Everywhere: the section says it too.
  text = std::regex_replace(results, std::regex("(^|[^\\d.])" + std::regex_replace(number, std::regex("\\."), "\\.") +
                                                "(?![\\d])"),
                            "$01" + changed);
  write(repo / "docs" / "RESULTS.md", text);
  EXPECT_EQ(check(repo), 0) << number << " changed to " << changed << " in both places";
  fs::remove_all(repo);
}

TEST(ResultsCheck, ANumberChangedInAMarkedReadmeParagraphOnlyFails) {
  const fs::path repo = copyDocs("readme");
  const std::string readme = bimanual_skills::testing::readTextFile((repo / "README.md").string());
  const std::size_t mark = readme.find("<!-- numbers:");
  ASSERT_NE(mark, std::string::npos) << "README marks no paragraph whose numbers are checked";
  const std::size_t start = readme.rfind("\n\n", mark);
  const std::string paragraph = readme.substr(start, mark - start);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(paragraph, m, std::regex(R"(\d+\.\d+)")));
  std::string text = readme;
  text.replace(start + static_cast<std::size_t>(m.position()), m.length(), "987.654");
  write(repo / "README.md", text);
  EXPECT_NE(check(repo), 0) << m.str() << " changed in README only";
  fs::remove_all(repo);
}
