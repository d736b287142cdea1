#include "mosaicloc/core/file.hpp"

#include <gtest/gtest.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::core {
namespace {

TEST(WriteFileAtomically, ReplacesWholeAndLeavesNoTemporary) {
  test::ScratchDir dir;
  WriteFileAtomically(dir / "a.txt", "first version, longer than the second");
  WriteFileAtomically(dir / "a.txt", "second");
  EXPECT_EQ(test::ReadFile(dir / "a.txt"), "second");
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 1);
}

TEST(WriteFileAtomically, FailureNamesTheFileAndKeepsTheOld) {
  test::ScratchDir dir;
  try {
    WriteFileAtomically(dir / "missing-dir" / "a.txt", "x");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kRuntime);
    EXPECT_NE(std::string(e.what()).find("missing-dir/a.txt"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mosaicloc::core
