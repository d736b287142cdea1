#include "mosaicloc/core/yaml.hpp"

#include <gtest/gtest.h>
#include <gmock/gmock.h>

#include "mosaicloc/core/error.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::core {
namespace {

using ::testing::HasSubstr;

struct CameraOptions {
  int width_px = 640;
  double mm_per_px = 0.25;
  std::string source = "simulator";
  bool strobe = true;
};

// Reads the way every options loader in the project does.
void ReadCamera(const YAML::Node& node, const std::string& file, CameraOptions* options,
                YamlProblems* problems) {
  YamlMap root = YamlMap::Root(node, file, problems);
  YamlMap camera = root.RequiredMap("camera");
  camera.Required("width_px", &options->width_px, PositiveInteger());
  camera.Optional("mm_per_px", &options->mm_per_px, InRange(0.001, 100.0));
  camera.Optional("source", &options->source, OneOf({"simulator", "dataset", "v4l2"}));
  camera.Optional("strobe", &options->strobe);
  camera.Finish();
  root.Finish();
}

TEST(YamlMap, ReadsValuesAndKeepsDefaults) {
  const YAML::Node node = YAML::Load("camera:\n  width_px: 800\n  source: v4l2\n");
  YamlProblems problems;
  CameraOptions options;
  ReadCamera(node, "site.yaml", &options, &problems);
  EXPECT_TRUE(problems.empty());
  EXPECT_EQ(options.width_px, 800);
  EXPECT_EQ(options.source, "v4l2");
  EXPECT_DOUBLE_EQ(options.mm_per_px, 0.25);
}

TEST(YamlMap, ReportsEveryProblemAtOnceWithLines) {
  const YAML::Node node = YAML::Load(
      "camera:\n"            // line 1
      "  mm_per_pix: 0.3\n"  // line 2: typo
      "  source: usb\n"      // line 3: not a choice
      "  strobe: maybe\n"    // line 4
      "extra: 1\n");         // line 5
  YamlProblems problems;
  CameraOptions options;
  ReadCamera(node, "site.yaml", &options, &problems);
  ASSERT_EQ(problems.messages().size(), 5u);
  const std::string all = [&] {
    std::string joined;
    for (const auto& m : problems.messages()) joined += m + "\n";
    return joined;
  }();
  EXPECT_THAT(all, HasSubstr("site.yaml:1: camera.width_px: missing required key"));
  EXPECT_THAT(all, HasSubstr("site.yaml:2: camera.mm_per_pix: unknown key (did you mean 'mm_per_px'?)"));
  EXPECT_THAT(all, HasSubstr("site.yaml:3: camera.source: must be one of simulator, dataset, v4l2, got 'usb'"));
  EXPECT_THAT(all, HasSubstr("site.yaml:4: camera.strobe: expected true or false"));
  EXPECT_THAT(all, HasSubstr("site.yaml:5: extra: unknown key"));
  // Defaults untouched where the input was bad.
  EXPECT_EQ(options.source, "simulator");
  try {
    problems.ThrowIfAny();
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kInvalidInput);
    EXPECT_THAT(e.what(), HasSubstr("5 configuration problems"));
  }
}

// YAML allows a mapping or a list as a key ("? {a: 1}"): a problem named with its line, like
// any unknown key, never an exception of the YAML library.
TEST(YamlMap, AKeyThatIsAMappingIsAProblemNotACrash) {
  const YAML::Node node = YAML::Load("camera:\n  width_px: 800\n  ? {a: 1}\n  : 2\n? [x]\n: 3\n");
  YamlProblems problems;
  CameraOptions options;
  ReadCamera(node, "site.yaml", &options, &problems);
  ASSERT_EQ(problems.messages().size(), 2u);
  EXPECT_THAT(problems.messages()[0], HasSubstr("site.yaml:3: "));
  EXPECT_THAT(problems.messages()[0], HasSubstr("a key must be a plain name"));
  EXPECT_THAT(problems.messages()[1], HasSubstr("site.yaml:5: "));
}

TEST(YamlMap, RejectsWrongTypesAndRanges) {
  const YAML::Node node = YAML::Load("camera:\n  width_px: 12.5\n  mm_per_px: -1\n");
  YamlProblems problems;
  CameraOptions options;
  ReadCamera(node, "f.yaml", &options, &problems);
  ASSERT_EQ(problems.messages().size(), 2u);
  EXPECT_THAT(problems.messages()[0], HasSubstr("f.yaml:2: camera.width_px: expected an integer, got '12.5'"));
  EXPECT_THAT(problems.messages()[1], HasSubstr("f.yaml:3: camera.mm_per_px: must be in [0.001, 100], got -1"));
}

TEST(YamlMap, MissingMapIsReportedOnce) {
  const YAML::Node node = YAML::Load("other: {}\n");
  YamlProblems problems;
  CameraOptions options;
  ReadCamera(node, "f.yaml", &options, &problems);
  ASSERT_EQ(problems.messages().size(), 2u);  // camera missing, 'other' unknown
  EXPECT_THAT(problems.messages()[0], HasSubstr("camera: missing required key"));
}

TEST(YamlMap, NumbersAreStrict) {
  const YAML::Node node = YAML::Load("camera:\n  width_px: 640px\n  mm_per_px: nan\n");
  YamlProblems problems;
  CameraOptions options;
  ReadCamera(node, "f.yaml", &options, &problems);
  EXPECT_EQ(problems.messages().size(), 2u);
}

TEST(LoadYamlFile, NamesFileAndLineOfSyntaxError) {
  test::ScratchDir dir;
  test::WriteFile(dir / "bad.yaml", "camera:\n  width_px: [1, 2\n");
  try {
    LoadYamlFile(dir / "bad.yaml");
    FAIL();
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("bad.yaml:"));
    EXPECT_THAT(e.what(), HasSubstr("YAML syntax error"));
  }
  EXPECT_THROW(LoadYamlFile(dir / "missing.yaml"), Error);
}

}  // namespace
}  // namespace mosaicloc::core
