#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <map>
#include <random>
#include <tuple>
#include <unordered_set>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "crc32.hpp"
#include "png_codec.hpp"
#include "mosaicloc/core/error.hpp"
#include "mosaicloc/mosaic/builder.hpp"
#include "mosaicloc/mosaic/prefetcher.hpp"
#include "mosaicloc/mosaic/renderer.hpp"
#include "mosaicloc/mosaic/tile_cache.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"
#include "mosaicloc/test/test_support.hpp"

namespace mosaicloc::mosaic {
namespace {

using ::testing::HasSubstr;
namespace fs = std::filesystem;

// A textured source image: the real asphalt when the shared data is there, else smoothed noise.
cv::Mat SourceTexture(int size) {
  if (const auto file = test::SharedTexture("asphalt_02_2048.jpg")) {
    cv::Mat grey = cv::imread(file->string(), cv::IMREAD_GRAYSCALE);
    return grey(cv::Rect(0, 0, size, size)).clone();
  }
  cv::Mat noise(size, size, CV_8UC1);
  cv::RNG rng(5);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.5);
  cv::normalize(noise, noise, 10, 250, cv::NORM_MINMAX);
  return noise;
}

// Stores `image` as level-0 pixels [0, cols) x [0, rows) (values clamped to [1, 255]).
void StoreImage(TileStore& store, const cv::Mat& image) {
  const int t = store.grid().tile_size_px;
  std::vector<TileWrite> tiles;
  for (int tr = 0; tr * t < image.rows; ++tr) {
    for (int tc = 0; tc * t < image.cols; ++tc) {
      cv::Mat tile = cv::Mat::zeros(t, t, CV_8UC1);
      const cv::Rect from(tc * t, tr * t, std::min(t, image.cols - tc * t), std::min(t, image.rows - tr * t));
      cv::max(image(from), 1, tile(cv::Rect(0, 0, from.width, from.height)));
      tiles.push_back({TileKey{0, tc, tr}, tile});
    }
  }
  store.Write(tiles);
}

TEST(MapGrid, PixelCentresFollowTheDesign) {
  MapGrid grid;
  grid.mm_per_px = 0.25;
  grid.origin_x_mm = -100.0;
  grid.origin_y_mm = 50.0;
  // Pixel (col 2, row 3) of level 0 has its centre at x0 + 2.5 r, y0 - 3.5 r.
  const Eigen::Vector2d world = grid.RasterToWorld({2.0, 3.0}, 0);
  EXPECT_DOUBLE_EQ(world.x(), -100.0 + 2.5 * 0.25);
  EXPECT_DOUBLE_EQ(world.y(), 50.0 - 3.5 * 0.25);
  // Level 2 pixel (0, 0) covers level-0 pixels [0, 4): its centre is at level-0 raster 1.5.
  const Eigen::Vector2d level0 = grid.WorldToRaster(grid.RasterToWorld({0.0, 0.0}, 2), 0);
  EXPECT_DOUBLE_EQ(level0.x(), 1.5);
  EXPECT_DOUBLE_EQ(level0.y(), 1.5);
  EXPECT_EQ(FloorDiv(-1, 256), -1);
  EXPECT_EQ(FloorDiv(-256, 256), -1);
  EXPECT_EQ(FloorDiv(255, 256), 0);
}

// The folded CRC-32 is zlib's, at every length and alignment, and chains like it.
TEST(Crc32, EqualsZlibsAtEveryLengthAndAlignment) {
  const char* check = "123456789";
  EXPECT_EQ(internal::Crc32Update(0, check, 9), 0xCBF43926u) << "the standard check value";
  std::vector<unsigned char> data(70000 + 16);
  std::mt19937 rng(4);
  for (unsigned char& b : data) b = static_cast<unsigned char>(rng());
  for (std::size_t offset = 0; offset < 16; offset += 3) {
    for (std::size_t bytes = 0; bytes <= 300; ++bytes) {
      ASSERT_EQ(internal::Crc32Update(0, data.data() + offset, bytes),
                internal::Crc32ZlibOnly(0, data.data() + offset, bytes))
          << bytes << " bytes at offset " << offset;
    }
    for (const std::size_t bytes : {1023u, 4096u, 65536u, 65537u, 70000u}) {
      ASSERT_EQ(internal::Crc32Update(0, data.data() + offset, bytes),
                internal::Crc32ZlibOnly(0, data.data() + offset, bytes))
          << bytes << " bytes at offset " << offset;
    }
  }
  const std::uint32_t first = internal::Crc32Update(0, data.data(), 1000);
  EXPECT_EQ(internal::Crc32Update(first, data.data() + 1000, 5000), internal::Crc32ZlibOnly(0, data.data(), 6000));
  std::vector<unsigned char> zeros(4096, 0), ones(4096, 0xFF);
  EXPECT_EQ(internal::Crc32Update(0, zeros.data(), zeros.size()), internal::Crc32ZlibOnly(0, zeros.data(), zeros.size()));
  EXPECT_EQ(internal::Crc32Update(0, ones.data(), ones.size()), internal::Crc32ZlibOnly(0, ones.data(), ones.size()));
}

TEST(TileStore, RoundTripAndMetadata) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.mm_per_px = 0.2;
  grid.origin_x_mm = 12.5;
  grid.tile_size_px = 64;
  {
    auto store = TileStore::Create(dir / "a.mosaic", grid);
    cv::Mat tile(64, 64, CV_8UC1);
    cv::randu(tile, 1, 255);
    store->Write({{TileKey{0, -3, 7}, tile}, {TileKey{1, 0, 0}, tile}});
    EXPECT_EQ(store->Count(), 2);
  }
  auto store = TileStore::Open(dir / "a.mosaic", false);
  EXPECT_DOUBLE_EQ(store->grid().mm_per_px, 0.2);
  EXPECT_DOUBLE_EQ(store->grid().origin_x_mm, 12.5);
  EXPECT_EQ(store->grid().tile_size_px, 64);
  EXPECT_EQ(store->Read(TileKey{0, -3, 7}).status, TileStatus::kOk);
  EXPECT_EQ(store->Read(TileKey{0, 0, 0}).status, TileStatus::kAbsent);
  ASSERT_EQ(store->List(0).size(), 1u);
  EXPECT_EQ(store->List(0)[0].col, -3);
  EXPECT_THROW(TileStore::Create(dir / "a.mosaic", grid), core::Error);
}

void SqlOn(const fs::path& file, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  sqlite3_close(db);
}

// The place index's cells: none in a new map; written whole, replaced whole, read back with
// their CRC checked; a damaged cell or metadata value is named.
TEST(TileStore, PlaceIndexCells) {
  test::ScratchDir dir;
  {
    auto store = TileStore::Create(dir / "p.mosaic", MapGrid{});
    EXPECT_FALSE(store->Places().has_value());
    EXPECT_THROW(store->ReadPlaces(), core::Error);
    PlaceIndexInfo info;
    info.format_version = 1;
    info.method = "orb256";
    info.level = 1;
    store->WritePlaces(info, {{0, 0, {1, 2, 3}}, {-2, 5, std::vector<unsigned char>(44, 7)}});
    store->WritePlaces(info, {{3, -1, {9, 8}}, {-2, 5, std::vector<unsigned char>(88, 5)}});
  }
  auto store = TileStore::Open(dir / "p.mosaic", false);
  const auto info = store->Places();
  ASSERT_TRUE(info.has_value());
  EXPECT_EQ(info->method, "orb256");
  EXPECT_EQ(info->level, 1);
  EXPECT_EQ(info->cells, 2);
  EXPECT_EQ(info->bytes, 90);
  const std::vector<PlaceCell> cells = store->ReadPlaces();
  ASSERT_EQ(cells.size(), 2u);
  EXPECT_EQ(cells[0].row, -1);  // by row, then column
  EXPECT_EQ(cells[0].data, (std::vector<unsigned char>{9, 8}));
  EXPECT_EQ(cells[1].data.size(), 88u);
  store.reset();
  SqlOn(dir / "p.mosaic", "UPDATE places SET data = X'0908FF' WHERE col = 3");
  try {
    TileStore::Open(dir / "p.mosaic", false)->ReadPlaces();
    ADD_FAILURE() << "a damaged cell was read";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("place index cell col 3 row -1: CRC32 mismatch"));
  }
  SqlOn(dir / "p.mosaic", "UPDATE metadata SET value = 'one' WHERE name = 'places_level'");
  try {
    TileStore::Open(dir / "p.mosaic", false)->Places();
    ADD_FAILURE() << "a bad metadata value was read";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("metadata key 'places_level' is not an integer: 'one'"));
  }
}

// The floor's self-test is kept with the index: absent until written, read back, forgotten when
// the index is rebuilt (the floor may have changed), and a damaged value is named.
TEST(TileStore, TheFloorsSelfTestIsKeptWithTheIndex) {
  test::ScratchDir dir;
  PlaceIndexInfo info;
  info.format_version = 1;
  info.method = "orb256";
  info.level = 1;
  {
    auto store = TileStore::Create(dir / "r.mosaic", MapGrid{});
    store->WritePlaces(info, {{0, 0, {1, 2, 3}}});
    EXPECT_EQ(store->Places()->repeat_test_views, -1);
    store->WritePlaceRepeatTest(24, 1, 23);
  }
  {
    auto store = TileStore::Open(dir / "r.mosaic", true);
    const auto read = store->Places();
    ASSERT_TRUE(read.has_value());
    EXPECT_EQ(read->repeat_test_views, 24);
    EXPECT_EQ(read->repeat_test_own, 1);
    EXPECT_EQ(read->repeat_test_elsewhere, 23);
    store->WritePlaces(info, {{0, 0, {4, 5}}});
    EXPECT_EQ(store->Places()->repeat_test_elsewhere, -1);
    store->WritePlaceRepeatTest(24, 24, 0);
  }
  SqlOn(dir / "r.mosaic", "UPDATE metadata SET value = '-3' WHERE name = 'places_repeat_test_own'");
  try {
    TileStore::Open(dir / "r.mosaic", false)->Places();
    ADD_FAILURE() << "a bad self-test value was read";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("metadata key 'places_repeat_test_own' is not a count: '-3'"));
  }
}

TEST(TileStore, QualityCellsAndTheirVerdicts) {
  test::ScratchDir dir;
  {
    auto store = TileStore::Create(dir / "q.mosaic", MapGrid{});
    EXPECT_FALSE(store->Quality().has_value());
    EXPECT_THROW(store->ReadQuality(), core::Error);
    EXPECT_THROW(store->WriteQuality(9, {}), core::Error);  // not a level of the map
    store->WriteQuality(1, {{0, 0, 1.0f, 30.0f, 0.2f}, {-2, 5, 0.6f, 2.5f, 0.97f}, {4, 4, 0.5f, -1.0f, -1.0f}});
  }
  auto store = TileStore::Open(dir / "q.mosaic", false);
  const auto info = store->Quality();
  ASSERT_TRUE(info.has_value());
  EXPECT_EQ(info->level, 1);
  EXPECT_EQ(info->cells, 3);
  const std::vector<QualityCell> cells = store->ReadQuality();
  ASSERT_EQ(cells.size(), 3u);
  EXPECT_EQ(cells[0].col, 0);  // by row, then column
  EXPECT_EQ(cells[2].row, 5);
  EXPECT_FLOAT_EQ(cells[2].ambiguity, 0.97f);
  const QualityThresholds thresholds;
  EXPECT_EQ(WeakBecause(cells[0], thresholds), "");
  EXPECT_EQ(WeakBecause(cells[2], thresholds), "little texture, repeats");
  EXPECT_EQ(WeakBecause(cells[1], thresholds), "");  // not judged: neither texture nor copies known
  EXPECT_EQ(WeakBecause({0, 0, 0.1f, 0.0f, 1.0f}, thresholds), "");  // a lane's edge
  store.reset();
  SqlOn(dir / "q.mosaic", "UPDATE quality SET ambiguity = 0.5 WHERE col = -2");
  try {
    TileStore::Open(dir / "q.mosaic", false)->ReadQuality();
    ADD_FAILURE() << "a damaged cell was read";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("quality cell col -2 row 5: CRC32 mismatch"));
  }
  SqlOn(dir / "q.mosaic", "UPDATE metadata SET value = '12' WHERE name = 'quality_level'");
  try {
    TileStore::Open(dir / "q.mosaic", false)->Quality();
    ADD_FAILURE() << "a bad level was read";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("metadata key 'quality_level' is not a level of the map: '12'"));
  }
}

// The stored size of one tile's PNG.
std::int64_t BlobBytes(const fs::path& file, const TileKey& key) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* statement = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(db, "SELECT length(data) FROM tiles WHERE level = ? AND col = ? AND row = ?", -1,
                               &statement, nullptr), SQLITE_OK);
  sqlite3_bind_int(statement, 1, key.level);
  sqlite3_bind_int64(statement, 2, key.col);
  sqlite3_bind_int64(statement, 3, key.row);
  const std::int64_t bytes = sqlite3_step(statement) == SQLITE_ROW ? sqlite3_column_int64(statement, 0) : -1;
  sqlite3_finalize(statement);
  sqlite3_close(db);
  return bytes;
}

TEST(TileStore, TilesOfEveryPngLevelReadBackExactly) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  cv::Mat texture = SourceTexture(64);
  cv::max(texture, 1, texture);
  {
    auto store = TileStore::Create(dir / "p.mosaic", grid);
    EXPECT_EQ(store->png_compression(), kDefaultTilePngCompression);
    EXPECT_THROW(store->SetPngCompression(10), core::Error);
    EXPECT_THROW(store->SetPngCompression(-1), core::Error);
    for (const int level : {0, 3, 9}) {
      store->SetPngCompression(level);
      store->Write({{TileKey{0, level, 0}, texture}});
    }
  }
  // A map written at another level (as maps were before level 0 was the default) opens and
  // reads the same pixels.
  auto store = TileStore::Open(dir / "p.mosaic", false);
  for (const int level : {0, 3, 9}) {
    const TileRead read = store->Read(TileKey{0, level, 0});
    ASSERT_EQ(read.status, TileStatus::kOk) << read.problem;
    EXPECT_EQ(cv::norm(read.pixels, texture, cv::NORM_INF), 0.0) << "level " << level;
  }
  // Level 0 stores the filtered rows as they are; the others do compress.
  const std::int64_t stored = BlobBytes(dir / "p.mosaic", TileKey{0, 0, 0});
  EXPECT_GE(stored, 64 * 65);
  EXPECT_LT(BlobBytes(dir / "p.mosaic", TileKey{0, 3, 0}), stored);
  EXPECT_LE(BlobBytes(dir / "p.mosaic", TileKey{0, 9, 0}), BlobBytes(dir / "p.mosaic", TileKey{0, 3, 0}));
}

// Replaces one tile's stored bytes with `png`, with a matching CRC32, as another writer
// (or a bug) would leave them.
void StoreRawTile(const fs::path& file, const TileKey& key, const std::vector<unsigned char>& png) {
  static const char* const kHex = "0123456789ABCDEF";
  std::string hex;
  for (const unsigned char byte : png) hex += {kHex[byte >> 4], kHex[byte & 15]};
  SqlOn(file, "INSERT OR REPLACE INTO tiles VALUES (" + std::to_string(key.level) + ", " + std::to_string(key.col) + ", " +
                  std::to_string(key.row) + ", X'" + hex + "', " + std::to_string(TileStore::Crc32(png)) + ")");
}

TEST(TileStore, PngsWrittenByOpenCvDecodeAlike) {
  // Maps written before the store encoded with libpng itself hold OpenCV's PNGs (row
  // filters chosen by OpenCV): they decode to the same pixels.
  cv::Mat texture = SourceTexture(64);
  for (const int level : {0, 3, 9}) {
    std::vector<unsigned char> png;
    ASSERT_TRUE(cv::imencode(".png", texture, png, {cv::IMWRITE_PNG_COMPRESSION, level}));
    cv::Mat pixels;
    EXPECT_EQ(TileStore::Decode(png, 64, pixels), "");
    EXPECT_EQ(cv::norm(pixels, texture, cv::NORM_INF), 0.0) << "level " << level;
    // And OpenCV reads what the store writes.
    EXPECT_EQ(cv::norm(cv::imdecode(TileStore::Encode(texture, level), cv::IMREAD_UNCHANGED), texture, cv::NORM_INF), 0.0);
  }
}

// The stored tiles the store writes take the copying fast path, tiles of the full 256 px
// size too (their rows span several IDAT chunks and stored blocks) and give libpng's pixels;
// anything else is left to libpng, and no cut or altered byte makes the fast path accept it.
TEST(TileStore, StoredTilesDecodeByCopyingAsLibpngDecodesThem) {
  for (const int size : {64, 256}) {
    const cv::Mat texture = SourceTexture(size);
    const std::vector<unsigned char> png = TileStore::Encode(texture, 0);
    cv::Mat fast;
    ASSERT_TRUE(internal::DecodeStoredGreyPng(png.data(), png.size(), size, fast)) << size;
    EXPECT_EQ(cv::norm(fast, texture, cv::NORM_INF), 0.0) << size;
    EXPECT_EQ(cv::norm(cv::imdecode(png, cv::IMREAD_UNCHANGED), texture, cv::NORM_INF), 0.0);
    cv::Mat scratch;
    EXPECT_FALSE(internal::DecodeStoredGreyPng(png.data(), png.size(), size / 2, scratch));
    for (std::size_t cut = 0; cut < png.size(); cut += 61) {
      EXPECT_FALSE(internal::DecodeStoredGreyPng(png.data(), cut, size, scratch)) << cut;
    }
    // Compressed rows go to libpng, which decodes them to the same pixels.
    const std::vector<unsigned char> compressed = TileStore::Encode(texture, 6);
    EXPECT_FALSE(internal::DecodeStoredGreyPng(compressed.data(), compressed.size(), size, scratch));
    cv::Mat decoded;
    EXPECT_EQ(TileStore::Decode(compressed, size, decoded), "");
    EXPECT_EQ(cv::norm(decoded, texture, cv::NORM_INF), 0.0);
  }
  // A row filter other than none, or a stored block whose length check fails, is not copied.
  const cv::Mat texture = SourceTexture(64);
  std::vector<unsigned char> png = TileStore::Encode(texture, 0);
  // Signature, IHDR, IDAT length and type, zlib header, stored block header: the first row's
  // filter byte.
  const std::size_t first_filter = 8 + 25 + 8 + 2 + 5;
  ASSERT_EQ(png[first_filter], 0);
  cv::Mat scratch;
  png[first_filter] = 1;
  EXPECT_FALSE(internal::DecodeStoredGreyPng(png.data(), png.size(), 64, scratch));
  png[first_filter] = 0;
  png[first_filter - 1] ^= 0x01;  // the block length's complement
  EXPECT_FALSE(internal::DecodeStoredGreyPng(png.data(), png.size(), 64, scratch));
}

TEST(TileStore, UndecodableAndMisshapenTilesAreNamed) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  const fs::path file = dir / "u.mosaic";
  const cv::Mat texture = SourceTexture(64);
  TileStore::Create(file, grid)->Write({{TileKey{0, 0, 0}, texture}});
  const std::vector<unsigned char> good = TileStore::Encode(texture);
  StoreRawTile(file, TileKey{0, 1, 0}, std::vector<unsigned char>(good.begin(), good.begin() + 2000));
  StoreRawTile(file, TileKey{0, 2, 0}, {'n', 'o', 't', ' ', 'a', ' ', 'p', 'n', 'g'});
  std::vector<unsigned char> deep, wide, colour;
  cv::Mat deep_pixels;
  texture.convertTo(deep_pixels, CV_16U, 256.0);
  ASSERT_TRUE(cv::imencode(".png", deep_pixels, deep));
  ASSERT_TRUE(cv::imencode(".png", SourceTexture(96)(cv::Rect(0, 0, 96, 64)), wide));
  cv::Mat colour_pixels;
  cv::cvtColor(texture, colour_pixels, cv::COLOR_GRAY2BGR);
  ASSERT_TRUE(cv::imencode(".png", colour_pixels, colour));
  StoreRawTile(file, TileKey{0, 3, 0}, deep);
  StoreRawTile(file, TileKey{0, 4, 0}, wide);
  StoreRawTile(file, TileKey{0, 5, 0}, colour);
  std::vector<unsigned char> damaged = good;  // the stored CRC matches, the PNG's own CRCs do not
  damaged[40] ^= 0x55;
  damaged[41] ^= 0x55;
  StoreRawTile(file, TileKey{0, 6, 0}, damaged);

  const auto store = TileStore::Open(file, false);
  EXPECT_EQ(store->Read(TileKey{0, 0, 0}).status, TileStatus::kOk);
  const std::vector<std::pair<int, std::string>> expected = {
      {1, "tile level 0 col 1 row 0: not a decodable PNG: the data ends early"},
      {2, "tile level 0 col 2 row 0: not a decodable PNG: no PNG signature"},
      {3, "tile level 0 col 3 row 0: is a 64 x 64 PNG of 16-bit samples"},
      {4, "tile level 0 col 4 row 0: is a 96 x 64 PNG of 8-bit samples, colour type 0, not an 8-bit grey 64 px square"},
      {5, "tile level 0 col 5 row 0: is a 64 x 64 PNG of 8-bit samples, colour type 2"}};
  for (const auto& [col, problem] : expected) {
    const TileRead read = store->Read(TileKey{0, col, 0});
    EXPECT_EQ(read.status, TileStatus::kCorrupt) << col;
    EXPECT_THAT(read.problem, HasSubstr(problem));
    EXPECT_TRUE(read.pixels.empty()) << col;
  }
  // Damage the outer CRC does not see decodes to wrong pixels or fails, never crashes.
  const TileRead damaged_read = store->Read(TileKey{0, 6, 0});
  if (damaged_read.status == TileStatus::kOk) {
    EXPECT_GT(cv::norm(damaged_read.pixels, texture, cv::NORM_INF), 0.0);
  }
}

TEST(TileStore, BadMetadataIsNamed) {
  test::ScratchDir dir;
  TileStore::Create(dir / "m.mosaic", MapGrid{});
  SqlOn(dir / "m.mosaic", "UPDATE metadata SET value = '7' WHERE name = 'format_version'");
  try {
    TileStore::Open(dir / "m.mosaic", false);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("format_version 7 is not supported"));
  }
  SqlOn(dir / "m.mosaic", "UPDATE metadata SET value = '1' WHERE name = 'format_version'; DELETE FROM metadata WHERE name = 'levels'");
  try {
    TileStore::Open(dir / "m.mosaic", false);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("metadata key 'levels' is missing"));
  }
  // A number no int holds, or not a whole one, is named before it becomes an int.
  for (const char* levels : {"7.8e43", "-3e12", "6.5"}) {
    SqlOn(dir / "m.mosaic", std::string("INSERT OR REPLACE INTO metadata VALUES ('levels', '") + levels + "')");
    try {
      TileStore::Open(dir / "m.mosaic", false);
      FAIL() << levels;
    } catch (const core::Error& e) {
      EXPECT_THAT(e.what(), HasSubstr(std::string("metadata key 'levels' must be a whole number within 2147483647: '") +
                                      levels + "'"));
    }
  }
  test::WriteFile(dir / "junk.mosaic", "this is not a database");
  EXPECT_THROW(TileStore::Open(dir / "junk.mosaic", false), core::Error);
  EXPECT_THROW(TileStore::Open(dir / "none.mosaic", false), core::Error);
}

TEST(TileStore, CorruptTileIsNamedAndTheRestStillWorks) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  {
    auto store = TileStore::Create(dir / "c.mosaic", grid);
    StoreImage(*store, SourceTexture(192));  // 3 x 3 tiles
  }
  // Flip bytes inside one tile's PNG, as a failing disk would.
  SqlOn(dir / "c.mosaic",
        "UPDATE tiles SET data = substr(data, 1, 100) || X'DEADBEEF' || substr(data, 105) WHERE col = 1 AND row = 2");
  auto store = TileStore::Open(dir / "c.mosaic", false);
  const TileRead bad = store->Read(TileKey{0, 1, 2});
  EXPECT_EQ(bad.status, TileStatus::kCorrupt);
  EXPECT_THAT(bad.problem, HasSubstr("tile level 0 col 1 row 2: CRC32 mismatch"));
  EXPECT_TRUE(bad.pixels.empty());
  // A view over the damaged tile renders the rest and reports the damage.
  TileCache cache(*store);
  const MapRenderer renderer(cache);
  const RasterPatch patch = renderer.Region(0, 0, 0, 192, 192);
  ASSERT_EQ(patch.problems.size(), 1u);
  EXPECT_EQ(cv::countNonZero(patch.mask), 192 * 192 - 64 * 64);
  EXPECT_EQ(cv::countNonZero(patch.image(cv::Rect(64, 128, 64, 64))), 0);
}

TEST(TileCache, StaysUnderBudgetAndCounts) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  auto store = TileStore::Create(dir / "b.mosaic", grid);
  StoreImage(*store, SourceTexture(512));  // 64 tiles of 4 KiB
  TileCache cache(*store, 10 * (64 * 64 + 512));
  for (int round = 0; round < 2; ++round) {
    for (int r = 0; r < 8; ++r) {
      for (int c = 0; c < 8; ++c) {
        EXPECT_EQ(cache.Get(TileKey{0, c, r})->status, TileStatus::kOk);
        EXPECT_LE(cache.stats().bytes, cache.budget_bytes());
      }
    }
  }
  const TileCacheStats stats = cache.stats();
  EXPECT_EQ(stats.misses, 128);  // cyclic access larger than the cache: LRU always misses
  EXPECT_EQ(stats.evictions, 118);
  EXPECT_EQ(stats.tiles, 10u);
  cache.Get(TileKey{0, 7, 7});
  EXPECT_EQ(cache.stats().hits, 1);
}

// A drive past floor never mapped asks for many absent tiles, and the budget counts each at a
// few hundred bytes: none may hold pixel memory, or the slabs grow without bound (a live run's
// prefetcher reaching along unmapped lanes grew them by 1.5 GiB an hour).
TEST(TileCache, AbsentTilesHoldNoPixelMemory) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  auto store = TileStore::Create(dir / "a.mosaic", grid);
  StoreImage(*store, SourceTexture(128));  // 2 x 2 tiles mapped
  TileCache cache(*store);
  for (int c = 0; c < 100; ++c) {
    for (int r = 0; r < 100; ++r) {
      const auto tile = cache.Get(TileKey{0, c, r});
      EXPECT_EQ(tile->status, c < 2 && r < 2 ? TileStatus::kOk : TileStatus::kAbsent);
    }
  }
  const TileCacheStats stats = cache.stats();
  EXPECT_EQ(stats.tiles, 10000u) << "absent tiles are cached: the store is not asked again";
  EXPECT_LE(stats.pool_bytes, std::size_t{64} * 64 * 64) << "one slab of 64 tiles: 4 mapped, 9996 absent";
  EXPECT_EQ(cache.Get(TileKey{0, 1, 1})->pixels.rows, 64);
}

TEST(TileStore, ReadersSeeEachTileOldOrNewWhileItIsRewritten) {
  // Readers use pooled connections of their own; each must see every committed write, and
  // while a write is in progress the state before it, never a mixture.
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  auto store = TileStore::Create(dir / "w.mosaic", grid);
  const auto uniform = [](int value) { return cv::Mat(64, 64, CV_8UC1, cv::Scalar(value)); };
  const auto write_all = [&](int value) {
    std::vector<TileWrite> tiles;
    for (int c = 0; c < 8; ++c) tiles.push_back({TileKey{0, c, 0}, uniform(value)});
    store->Write(tiles);
  };
  write_all(1);
  std::atomic<bool> done{false};
  std::atomic<int> mixed{0}, reads{0};
  std::vector<std::thread> readers;
  for (int i = 0; i < 3; ++i) {
    readers.emplace_back([&] {
      while (!done) {
        for (int c = 0; c < 8; ++c) {
          const TileRead read = store->Read(TileKey{0, c, 0});
          double lo = 0, hi = 0;
          if (read.status == TileStatus::kOk) cv::minMaxLoc(read.pixels, &lo, &hi);
          if (read.status != TileStatus::kOk || lo != hi) ++mixed;
          ++reads;
        }
      }
    });
  }
  for (int value = 2; value <= 40; ++value) {
    write_all(value);
    // Every read from now on, on any connection, sees this write.
    for (int c = 0; c < 8; ++c) EXPECT_EQ(store->Read(TileKey{0, c, 0}).pixels.at<std::uint8_t>(5, 5), value);
  }
  done = true;
  for (auto& reader : readers) reader.join();
  EXPECT_EQ(mixed.load(), 0);
  EXPECT_GT(reads.load(), 0);
}

TEST(TileCache, ConcurrentReadersAgree) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  auto store = TileStore::Create(dir / "t.mosaic", grid);
  const cv::Mat source = SourceTexture(512);
  StoreImage(*store, source);
  TileCache cache(*store, 16 * (64 * 64 + 512));
  std::vector<std::thread> threads;
  std::atomic<int> mismatches{0};
  for (int i = 0; i < 4; ++i) {
    threads.emplace_back([&, i] {
      std::mt19937 rng(i);
      for (int n = 0; n < 300; ++n) {
        const int c = static_cast<int>(rng() % 8), r = static_cast<int>(rng() % 8);
        const auto tile = cache.Get(TileKey{0, c, r});
        cv::Mat expected;
        cv::max(source(cv::Rect(c * 64, r * 64, 64, 64)), 1, expected);
        if (cv::norm(tile->pixels, expected, cv::NORM_INF) != 0) ++mismatches;
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(mismatches.load(), 0);
  EXPECT_LE(cache.stats().bytes, cache.budget_bytes());
}

TEST(MapBuilder, PaintedMapReproducesTheFrames) {
  const cv::Mat source = SourceTexture(1024);  // the "floor": raster pixel = source pixel, 0.25 mm
  MapGrid grid;
  grid.tile_size_px = 128;
  grid.levels = 3;
  for (const Blend blend : {Blend::kFeather, Blend::kBestView}) {
    MapBuilder builder(grid, blend);
    // Each frame with the warp that made it from the floor (frame pixel -> raster).
    std::vector<std::pair<cv::Mat, cv::Mat>> frames;
    for (int i = 0; i < 12; ++i) {
      // Overlapping frames along a gentle curve, each the exact view of the floor there.
      const core::Pose2 pose(60.0 + 12.0 * i, -120.0 - 3.0 * i, 0.05 * i);
      cv::Mat map(2, 3, CV_64F);
      const Eigen::Matrix2d r = pose.Rotation();
      const Eigen::Vector2d centre = grid.WorldToRaster(pose.translation_mm(), 0);
      map.at<double>(0, 0) = r(0, 0);
      map.at<double>(0, 1) = -r(0, 1);
      map.at<double>(1, 0) = -r(1, 0);
      map.at<double>(1, 1) = r(1, 1);
      map.at<double>(0, 2) = centre.x() - map.at<double>(0, 0) * 159.5 - map.at<double>(0, 1) * 119.5;
      map.at<double>(1, 2) = centre.y() - map.at<double>(1, 0) * 159.5 - map.at<double>(1, 1) * 119.5;
      cv::Mat frame;
      cv::warpAffine(source, frame, map, cv::Size(320, 240), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
      builder.AddFrame(frame, pose, 0.25);
      frames.emplace_back(map, frame);
    }
    test::ScratchDir dir;
    auto store = TileStore::Create(dir / "p.mosaic", grid);
    builder.Write(*store);
    EXPECT_GT(store->Count(2), 0);
    TileCache cache(*store);
    const MapRenderer renderer(cache);
    // The painted level 0 over the whole floor, warped as the floor was into each frame.
    const RasterPatch painted = renderer.Region(0, 0, 0, source.cols, source.rows);
    for (const auto& [map, frame] : frames) {
      cv::Mat view, mapped;
      cv::warpAffine(painted.image, view, map, frame.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
      cv::warpAffine(painted.mask, mapped, map, frame.size(), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP);
      EXPECT_GT(cv::countNonZero(mapped), 0.99 * static_cast<double>(mapped.total()));
      EXPECT_GT(test::Zncc(view, frame, mapped), 0.98);
    }
  }
}

TEST(MapBuilder, AFrameOnTheGridPaintsItsPixelsAndAHalfPixelRimBeyond) {
  MapGrid grid;
  grid.tile_size_px = 64;
  grid.levels = 1;
  cv::Mat frame = SourceTexture(256)(cv::Rect(0, 0, 100, 80)).clone();
  cv::max(frame, 1, frame);
  // Frame pixel centres on map pixel centres: its pixel (u, v) is map pixel (30 + u, 20 + v).
  const double s = grid.mm_per_px;
  const core::Pose2 on_grid((30 + 49.5 + 0.5) * s, -(20 + 39.5 + 0.5) * s, 0.0);
  // Half a pixel off: the map pixels whose centres lie on the frame's edges get painted too.
  const core::Pose2 half_off = on_grid * core::Pose2(0.5 * s, -0.5 * s, 0.0);
  for (const Blend blend : {Blend::kFeather, Blend::kBestView}) {
    for (const bool shifted : {false, true}) {
      MapBuilder builder(grid, blend);
      builder.AddFrame(frame, shifted ? half_off : on_grid, s);
      cv::Mat painted = cv::Mat::zeros(256, 256, CV_8UC1);
      for (int tr = 0; tr < 4; ++tr) {
        for (int tc = 0; tc < 4; ++tc) {
          try {
            builder.FinishTile(TileKey{0, tc, tr}).copyTo(painted(cv::Rect(tc * 64, tr * 64, 64, 64)));
          } catch (const std::out_of_range&) {
          }
        }
      }
      const cv::Rect footprint = shifted ? cv::Rect(30, 20, 101, 81) : cv::Rect(30, 20, 100, 80);
      EXPECT_EQ(cv::countNonZero(painted), footprint.area()) << "shifted " << shifted;
      EXPECT_EQ(cv::countNonZero(painted(footprint)), footprint.area()) << "shifted " << shifted;
      if (!shifted) {
        // Bicubic weights at a whole-pixel offset are (0, 1, 0, 0): the pixels themselves.
        EXPECT_EQ(cv::norm(painted(footprint), frame, cv::NORM_INF), 0.0);
      }
    }
  }
}

// A frame from a pinhole (f = 800 px) 200 mm over a flat floor, pitched and rolled by 1.1 and
// 0.9 degrees: rendered ray by ray in world axes, then painted as its camera saw the floor and
// as if it had looked straight down from its optical axis's foot. The slant's keystone (up to
// tilt r^2 / 2h, 0.3 px at this frame's corners) is in the second, not in the first.
TEST(MapBuilder, ATiltedCamerasFrameIsPaintedWhereItSawTheFloor) {
  // The floor (raster pixel = source pixel, 0.25 mm), smoothed so that resampling it twice
  // (rendered, painted) costs little beside the geometry.
  cv::Mat source;
  cv::GaussianBlur(SourceTexture(1024), source, cv::Size(0, 0), 1.0);
  MapGrid grid;
  grid.tile_size_px = 128;
  grid.levels = 1;
  const double f = 800.0, cx = 159.5, cy = 119.5;
  const Eigen::Vector3d lens(128.0, -128.0, 200.0);
  const double yaw = 0.3;
  const Eigen::Matrix3d world_from_camera =
      (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.016, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(-0.019, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  // Each pixel's ray onto the floor z = 0, as a raster position of the source.
  cv::Mat map_x(240, 320, CV_32F), map_y(240, 320, CV_32F);
  const auto on_floor = [&](const Eigen::Vector3d& ray_camera) {
    const Eigen::Vector3d d = world_from_camera * ray_camera;
    return Eigen::Vector2d((lens - lens.z() / d.z() * d).head<2>());
  };
  for (int v = 0; v < 240; ++v) {
    for (int u = 0; u < 320; ++u) {
      const Eigen::Vector2d floor = on_floor(Eigen::Vector3d(u - cx, -(v - cy), -f));
      map_x.at<float>(v, u) = static_cast<float>(floor.x() / 0.25 - 0.5);
      map_y.at<float>(v, u) = static_cast<float>(-floor.y() / 0.25 - 0.5);
    }
  }
  cv::Mat frame;
  cv::remap(source, frame, map_x, map_y, cv::INTER_CUBIC, cv::BORDER_REPLICATE);
  // What the camera's geometry records: the floor's normal in camera axes, the optical axis's
  // foot and the distance to the floor.
  const Eigen::Vector3d n = world_from_camera.transpose() * Eigen::Vector3d::UnitZ();
  const double tilt_x = std::atan2(n.y(), n.z()), tilt_y = std::atan2(-n.x(), n.z());
  const core::Pose2 view(on_floor(Eigen::Vector3d(0.0, 0.0, -1.0)), yaw);
  const double mm_per_px = lens.z() / f;

  const auto painted_error = [&](bool tilted) {
    MapBuilder builder(grid, Blend::kFeather);
    if (tilted) {
      builder.AddFrame(frame, view, mm_per_px, f, tilt_x, tilt_y);
    } else {
      builder.AddFrame(frame, view, mm_per_px);
    }
    cv::Mat painted = cv::Mat::zeros(1024, 1024, CV_8UC1);
    for (const TileKey& key : builder.TileKeys()) {
      if (key.col < 0 || key.row < 0 || key.col >= 8 || key.row >= 8) continue;
      const cv::Rect place(static_cast<int>(key.col) * 128, static_cast<int>(key.row) * 128, 128, 128);
      builder.FinishTile(key).copyTo(painted(place));
    }
    // The floor the frame saw, three pixels in from its edges.
    cv::Mat inside = cv::Mat::zeros(1024, 1024, CV_8UC1);
    std::vector<cv::Point> corners;
    for (const auto& [u, v] : {std::pair(3.0, 3.0), {316.0, 3.0}, {316.0, 236.0}, {3.0, 236.0}}) {
      const Eigen::Vector2d floor = on_floor(Eigen::Vector3d(u - cx, -(v - cy), -f));
      corners.emplace_back(static_cast<int>(std::lround(floor.x() / 0.25)),
                           static_cast<int>(std::lround(-floor.y() / 0.25)));
    }
    cv::fillConvexPoly(inside, corners, cv::Scalar(255));
    EXPECT_EQ(cv::countNonZero(painted(cv::Rect(0, 0, 1024, 1024)) & inside), cv::countNonZero(inside));
    cv::Mat difference;
    cv::absdiff(painted, source, difference);
    return cv::mean(difference, inside)[0];
  };
  const double tilted = painted_error(true), straight = painted_error(false);
  std::printf("mean |painted - floor|: %.3f DN as seen, %.3f DN straight down\n", tilted, straight);
  EXPECT_LT(tilted, 0.3 * straight);
  EXPECT_LT(tilted, 0.5);
}

TEST(TileStore, KilledWriterLeavesEveryTileOldOrNew) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  const fs::path file = dir / "k.mosaic";
  {
    auto store = TileStore::Create(file, grid);
    std::vector<TileWrite> tiles;
    for (int c = 0; c < 16; ++c) tiles.push_back({TileKey{0, c, 0}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(10))});
    store->Write(tiles);
  }
  int updated = 0;
  for (int attempt = 0; attempt < 5; ++attempt) {
    // The child says when its first pass is committed: then it is killed at some moment of a
    // later one, however slowly it runs (a sanitizer build).
    int committed[2];
    ASSERT_EQ(pipe(committed), 0);
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      // Rewrites all tiles again and again, each pass in one transaction, new value per pass.
      close(committed[0]);
      auto store = TileStore::Open(file, true);
      for (int pass = 0;; ++pass) {
        std::vector<TileWrite> tiles;
        for (int c = 0; c < 16; ++c) {
          tiles.push_back({TileKey{0, c, 0}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(20 + pass % 200))});
        }
        store->Write(tiles);
        if (pass == 0) {
          const char one = 1;
          if (write(committed[1], &one, 1) != 1) _exit(1);
        }
      }
    }
    close(committed[1]);
    char one = 0;
    ASSERT_EQ(read(committed[0], &one, 1), 1) << "the writer died before its first commit";
    close(committed[0]);
    usleep(3000 + 7000 * attempt);
    kill(child, SIGKILL);
    waitpid(child, nullptr, 0);
    auto store = TileStore::Open(file, false);
    int first_value = -1;
    for (int c = 0; c < 16; ++c) {
      const TileRead read = store->Read(TileKey{0, c, 0});
      ASSERT_EQ(read.status, TileStatus::kOk) << read.problem;
      double lo = 0, hi = 0;
      cv::minMaxLoc(read.pixels, &lo, &hi);
      EXPECT_EQ(lo, hi);  // never a half-written tile
      if (first_value < 0) first_value = static_cast<int>(lo);
      EXPECT_EQ(static_cast<int>(lo), first_value);  // one transaction: all tiles from the same pass
    }
    if (first_value != 10) ++updated;
  }
  EXPECT_GT(updated, 0) << "the writer never committed before it was killed: the test proved nothing";
}

}  // namespace
}  // namespace mosaicloc::mosaic

namespace mosaicloc::mosaic {
namespace {

TEST(TilePrefetcher, WarmsTheTilesAheadSoRendersDoNotWait) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  auto store = TileStore::Create(dir / "f.mosaic", grid);
  StoreImage(*store, SourceTexture(1024));  // 256 x 256 mm from (0, 0) to (256, -256)
  TileCache cache(*store);
  const MapRenderer renderer(cache);
  PrefetchOptions options;
  options.view_radius_mm = 30.0;  // a 160 x 120 px view at 0.25 mm is 40 x 30 mm: half diagonal 25 mm
  options.horizon_s = 1.0;
  TilePrefetcher prefetcher(cache, options);
  // Driving along y = -128 mm at 100 mm/s: predict, let the prefetcher work, then read the
  // view's pixels where the vehicle will be half a second later.
  int waited = 0;
  for (double x = 40.0; x <= 200.0; x += 20.0) {
    const core::Pose2 pose(x, -128.0, 0.0);
    prefetcher.Predict(pose, {100.0, 0.0}, 0.0);
    prefetcher.WaitIdle();
    waited += renderer.PatchAround({x + 50.0, -128.0}, 160, 120, 0).tiles_loaded;
  }
  EXPECT_EQ(waited, 0);
  EXPECT_GT(prefetcher.tiles_requested(), 0);
  // Without a prediction the read ahead has to load.
  TileCache cold(*store);
  const MapRenderer cold_renderer(cold);
  EXPECT_GT(cold_renderer.PatchAround({90.0, -128.0}, 160, 120, 0).tiles_loaded, 0);
}

TEST(TilePrefetcher, PlansNearestFirstAndCoversTheTurnsItMayTake) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;  // 16 mm tiles
  auto store = TileStore::Create(dir / "p.mosaic", grid);
  TileCache cache(*store);
  PrefetchOptions straight;
  straight.view_radius_mm = 20.0;
  straight.horizon_s = 1.0;
  straight.threads = 1;
  PrefetchOptions branching = straight;
  branching.min_turn_radius_mm = 100.0;
  branching.branch_mm = 150.0;
  const TilePrefetcher::Prediction prediction{core::Pose2(0.0, 0.0, 0.0), {200.0, 0.0}, 0.0};
  const std::vector<TileKey> plan = TilePrefetcher(cache, straight).Plan(prediction);
  const std::vector<TileKey> wide = TilePrefetcher(cache, branching).Plan(prediction);
  ASSERT_FALSE(plan.empty());
  // No repeats, and the tiles come in order of the distance along the path.
  std::unordered_set<TileKey, TileKeyHash> unique(plan.begin(), plan.end());
  EXPECT_EQ(unique.size(), plan.size());
  const auto tile_x_mm = [&](const TileKey& key) { return grid.RasterToWorld({(key.col + 0.5) * 64.0, 0.0}, 0).x(); };
  // The discs 40 mm apart each add tiles up to radius + half a tile either side of them.
  double furthest = -1e9;
  for (const TileKey& key : plan) {
    EXPECT_GE(tile_x_mm(key), furthest - 2 * (20.0 + 8.0) - 1e-9);
    furthest = std::max(furthest, tile_x_mm(key));
  }
  EXPECT_LT(std::abs(tile_x_mm(plan.front())), 28.0);
  EXPECT_GT(tile_x_mm(plan.back()), 190.0);  // 200 mm ahead, the horizon
  // Straight ahead, every tile lies within the radius of the line y = 0.
  const auto tile_y_mm = [&](const TileKey& key) { return grid.RasterToWorld({0.0, (key.row + 0.5) * 64.0}, 0).y(); };
  for (const TileKey& key : plan) EXPECT_LT(std::abs(tile_y_mm(key)), 20.0 + 8.0 + 1e-9);
  // With branches: everything of the straight plan, plus the tiles of 100 mm radius turns
  // either way (a quarter circle reaches y = +-100 mm at x = 100 mm after 157 mm).
  const std::unordered_set<TileKey, TileKeyHash> wide_set(wide.begin(), wide.end());
  for (const TileKey& key : plan) EXPECT_EQ(wide_set.count(key), 1u);
  double left = 0.0, right = 0.0;
  for (const TileKey& key : wide) {
    left = std::max(left, tile_y_mm(key));
    right = std::min(right, tile_y_mm(key));
  }
  EXPECT_GT(left, 70.0);
  EXPECT_LT(right, -70.0);
  // The branches are taken only as far as branch_mm.
  for (const TileKey& key : wide) EXPECT_LT(std::abs(tile_y_mm(key)), 150.0 * 150.0 / (2 * 100.0) + 28.0);
}

}  // namespace
}  // namespace mosaicloc::mosaic

namespace mosaicloc::mosaic {
namespace {

TEST(WriteWithPyramid, UpdatedTileKeepsEveryLevelConsistent) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  grid.levels = 4;
  // A map built from a texture, then one level-0 tile replaced by a flat patch.
  const cv::Mat source = SourceTexture(512);
  auto store = TileStore::Create(dir / "w.mosaic", grid);
  StoreImage(*store, source);
  std::vector<TileWrite> level0;
  for (const auto& key : store->List(0)) level0.push_back({key, store->Read(key).pixels});
  WriteWithPyramid(*store, level0);
  EXPECT_EQ(store->Count(1), 16);
  EXPECT_EQ(store->Count(3), 1);

  WriteWithPyramid(*store, {{TileKey{0, 5, 2}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(200))}});
  // Every level's pixels equal the 2^k x 2^k mean of level 0 (all mapped here).
  TileCache cache(*store);
  const MapRenderer renderer(cache);
  const RasterPatch level_0 = renderer.Region(0, 0, 0, 512, 512);
  for (int k = 1; k < 4; ++k) {
    const int size = 512 >> k;
    cv::Mat expected = level_0.image.clone();
    for (int i = 0; i < k; ++i) cv::resize(expected, expected, cv::Size(expected.cols / 2, expected.rows / 2), 0, 0, cv::INTER_AREA);
    const RasterPatch level_k = renderer.Region(k, 0, 0, size, size);
    cv::Mat difference;
    cv::absdiff(level_k.image, expected, difference);
    EXPECT_LE(cv::norm(difference, cv::NORM_INF), k) << "level " << k;  // rounding at each level
  }
  // The changed area shows at level 3: tile (5, 2) of level 0 is pixels 40..47 x 16..23 there.
  EXPECT_NEAR(cv::mean(renderer.Region(3, 40, 16, 8, 8).image)[0], 200.0, 1.0);
}

// Every tile of every level, as stored.
std::map<std::tuple<int, std::int64_t, std::int64_t>, cv::Mat> AllTiles(const TileStore& store) {
  std::map<std::tuple<int, std::int64_t, std::int64_t>, cv::Mat> tiles;
  for (const TileKey& key : store.List()) tiles[{key.level, key.col, key.row}] = store.Read(key).pixels;
  return tiles;
}

bool SameTiles(const std::map<std::tuple<int, std::int64_t, std::int64_t>, cv::Mat>& a,
               const std::map<std::tuple<int, std::int64_t, std::int64_t>, cv::Mat>& b) {
  if (a.size() != b.size()) return false;
  for (const auto& [key, pixels] : a) {
    const auto it = b.find(key);
    if (it == b.end() || cv::norm(pixels, it->second, cv::NORM_INF) != 0.0) return false;
  }
  return true;
}

// Recorded writes keep the level-0 tiles they replace; reverting them, newest first, gives back
// the map as it was, pyramid and all, and a tile an update added is removed again.
TEST(MapHistory, RevertingUpdatesGivesBackTheMapExactly) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  grid.levels = 3;
  auto store = TileStore::Create(dir / "h.mosaic", grid);
  const cv::Mat source = SourceTexture(256);
  std::vector<TileWrite> level0;
  for (int row = 0; row < 4; ++row) {
    for (int col = 0; col < 4; ++col) {
      cv::Mat pixels;
      cv::max(source(cv::Rect(64 * col, 64 * row, 64, 64)), 1, pixels);
      level0.push_back({TileKey{0, col, row}, pixels});
    }
  }
  WriteWithPyramid(*store, level0);
  EXPECT_TRUE(store->History().empty());  // a plain write is not recorded
  const auto original = AllTiles(*store);

  const auto first = WriteWithPyramid(*store, {{TileKey{0, 1, 1}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(90))}}, "a stain");
  const auto second = WriteWithPyramid(*store,
                                       {{TileKey{0, 1, 1}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(120))},
                                        {TileKey{0, 4, 0}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(60))}},
                                       "a new tile, beyond the map's edge");
  ASSERT_TRUE(first && second);
  const std::vector<MapUpdate> history = store->History();
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[0].id, *first);
  EXPECT_EQ(history[0].reason, "a stain");
  EXPECT_EQ(history[0].tiles, 1);
  EXPECT_EQ(history[1].tiles, 2);
  EXPECT_EQ(history[0].time.size(), 20u) << history[0].time;  // 2026-12-05T03:12:45Z
  EXPECT_TRUE(history[0].reverted.empty());

  // The older one is under the newer one: it cannot be undone alone.
  try {
    RevertUpdate(*store, *first);
    FAIL() << "reverted an update a later one built on";
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("update " + std::to_string(*second)));
    EXPECT_THAT(e.what(), HasSubstr("revert that one first"));
  }
  const RevertSummary undone = RevertUpdate(*store, *second);
  EXPECT_EQ(undone.restored, 1);
  EXPECT_EQ(undone.removed, 1);
  EXPECT_EQ(store->Read(TileKey{0, 4, 0}).status, TileStatus::kAbsent);
  EXPECT_EQ(store->Read(TileKey{2, 1, 0}).status, TileStatus::kAbsent);  // nothing mapped under it any more
  EXPECT_NEAR(cv::mean(store->Read(TileKey{0, 1, 1}).pixels)[0], 90.0, 1e-9);
  RevertUpdate(*store, *first);
  EXPECT_TRUE(SameTiles(AllTiles(*store), original));
  EXPECT_FALSE(store->History()[0].reverted.empty());
  EXPECT_THROW(RevertUpdate(*store, *first), core::Error);  // already reverted
  try {
    RevertUpdate(*store, 99);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("update 99: no such update"));
  }
}

// A kept tile that was damaged on disk is named, and the revert changes nothing.
TEST(MapHistory, DamagedKeptTileIsNamedAndNothingChanges) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  grid.levels = 2;
  auto store = TileStore::Create(dir / "d.mosaic", grid);
  WriteWithPyramid(*store, {{TileKey{0, 0, 0}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(50))}});
  const auto id = WriteWithPyramid(*store, {{TileKey{0, 0, 0}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(70))}}, "update");
  ASSERT_TRUE(id);
  store.reset();
  SqlOn(dir / "d.mosaic", "UPDATE replaced SET crc32 = crc32 + 1;");
  store = TileStore::Open(dir / "d.mosaic", true);
  try {
    RevertUpdate(*store, *id);
    FAIL();
  } catch (const core::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("kept tile level 0 col 0 row 0: CRC mismatch"));
  }
  EXPECT_NEAR(cv::mean(store->Read(TileKey{0, 0, 0}).pixels)[0], 70.0, 1e-9);
  EXPECT_TRUE(store->History()[0].reverted.empty());
}

// A map written before the history existed has none, opens read-only as before, and gets its
// history with the first recorded write.
TEST(MapHistory, AMapWithoutHistoryGetsOneWithItsFirstRecordedWrite) {
  test::ScratchDir dir;
  MapGrid grid;
  grid.tile_size_px = 64;
  grid.levels = 1;
  TileStore::Create(dir / "o.mosaic", grid)->Write({{TileKey{0, 0, 0}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(9))}});
  EXPECT_TRUE(TileStore::Open(dir / "o.mosaic", false)->History().empty());
  EXPECT_THROW(TileStore::Open(dir / "o.mosaic", false)->Replaced(1), core::Error);
  auto store = TileStore::Open(dir / "o.mosaic", true);
  store->WriteRecorded({{TileKey{0, 0, 0}, cv::Mat(64, 64, CV_8UC1, cv::Scalar(10))}}, "first");
  EXPECT_EQ(TileStore::Open(dir / "o.mosaic", false)->History().size(), 1u);
  EXPECT_THROW(store->WriteRecorded({}, ""), core::Error);
}

}  // namespace
}  // namespace mosaicloc::mosaic
