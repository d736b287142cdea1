// A map file's metadata (TileStore::Open, Places, Quality, History; what `map info`, `replay`
// and the console read first). The input edits the metadata table of a valid map, one line
// each: "name=value" sets a key, "name" alone removes it; the map is then opened and read as
// every command does.
#include <sqlite3.h>

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/core.hpp>

#include "fuzz_input.hpp"
#include "mosaicloc/mosaic/tile_store.hpp"

namespace {

using mosaicloc::mosaic::TileStore;

// A map with tiles, an update in its history, a place index and a quality layer, and an open
// connection to edit its metadata with; made once per process.
struct Template {
  std::filesystem::path file = mosaicloc::fuzz::ScratchDir() / "site.mosaic";
  sqlite3* db = nullptr;
  std::vector<std::pair<std::string, std::string>> metadata;

  Template() {
    std::filesystem::remove(file);
    {
      mosaicloc::mosaic::MapGrid grid;
      grid.tile_size_px = 32;
      grid.levels = 2;
      auto store = TileStore::Create(file, grid);
      cv::Mat pixels(32, 32, CV_8UC1, cv::Scalar(90));
      store->Write({{{0, 0, 0}, pixels}, {{1, 0, 0}, pixels}});
      store->WriteRecorded({{{0, 1, 0}, pixels}}, "a changed lane");
      mosaicloc::mosaic::PlaceIndexInfo places;
      places.format_version = 1;
      places.method = "orb256";
      places.level = 1;
      store->WritePlaces(places, {{0, 0, {1, 2, 3}}});
      store->WritePlaceRepeatTest(10, 9, 1);
      store->WriteQuality(1, {{0, 0, 1.0f, 30.0f, 0.2f}});
    }
    if (sqlite3_open(file.c_str(), &db) != SQLITE_OK) __builtin_trap();
    sqlite3_exec(db, "PRAGMA synchronous=OFF", nullptr, nullptr, nullptr);
    sqlite3_stmt* select = nullptr;
    sqlite3_prepare_v2(db, "SELECT name, value FROM metadata", -1, &select, nullptr);
    while (sqlite3_step(select) == SQLITE_ROW) {
      metadata.emplace_back(reinterpret_cast<const char*>(sqlite3_column_text(select, 0)),
                            reinterpret_cast<const char*>(sqlite3_column_text(select, 1)));
    }
    sqlite3_finalize(select);
  }

  void Run(sqlite3_stmt* statement, std::string_view a, std::string_view b = {}) const {
    sqlite3_reset(statement);
    sqlite3_bind_text(statement, 1, a.data(), static_cast<int>(a.size()), SQLITE_TRANSIENT);
    if (sqlite3_bind_parameter_count(statement) > 1) {
      sqlite3_bind_text(statement, 2, b.data(), static_cast<int>(b.size()), SQLITE_TRANSIENT);
    }
    sqlite3_step(statement);
  }

  // The template's metadata, then the input's edits, committed.
  void Edit(std::string_view edits) const {
    sqlite3_exec(db, "BEGIN; DELETE FROM metadata;", nullptr, nullptr, nullptr);
    sqlite3_stmt* set = nullptr;
    sqlite3_stmt* remove = nullptr;
    sqlite3_prepare_v2(db, "INSERT OR REPLACE INTO metadata VALUES (?, ?)", -1, &set, nullptr);
    sqlite3_prepare_v2(db, "DELETE FROM metadata WHERE name = ?", -1, &remove, nullptr);
    for (const auto& [name, value] : metadata) Run(set, name, value);
    while (!edits.empty()) {
      const std::size_t end = edits.find('\n');
      const std::string_view line = edits.substr(0, end);
      edits = end == std::string_view::npos ? std::string_view() : edits.substr(end + 1);
      const std::size_t equals = line.find('=');
      if (equals == std::string_view::npos) {
        Run(remove, line);
      } else {
        Run(set, line.substr(0, equals), line.substr(equals + 1));
      }
    }
    sqlite3_finalize(set);
    sqlite3_finalize(remove);
    sqlite3_exec(db, "COMMIT;", nullptr, nullptr, nullptr);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const Template map;
  map.Edit(std::string_view(reinterpret_cast<const char*>(data), size));
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] {
    const std::unique_ptr<TileStore> store = TileStore::Open(map.file, false);
    store->Places();
    store->Quality();
    store->History();
    store->Count();
    for (const auto& key : store->List()) store->Read(key);
  });
  return 0;
}
