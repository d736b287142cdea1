#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "mosaicloc/mosaic/grid.hpp"

struct sqlite3;

namespace mosaicloc::mosaic {

inline constexpr int kMapFormatVersion = 1;
/// Pixel value that means "not mapped". Painted pixels are clamped to [1, 255].
inline constexpr std::uint8_t kUnmapped = 0;

/// zlib level of the tiles' PNGs when none is chosen: 0, stored (uncompressed) deflate
/// blocks. Floor texture is noise to deflate: levels 1-9 and every zlib strategy shrink a
/// tile by only 17-32 % (procedural concrete and asphalt at 0.25 mm/px: 17-20 %), while
/// inflating their Huffman codes costs about 4 times the instructions of the whole decode of a
/// stored tile (5.1-5.4 M against 1.3-1.5 M per 256 px tile). Any level reads back the same:
/// maps written at other levels open unchanged.
inline constexpr int kDefaultTilePngCompression = 0;

/// Outcome of reading one tile.
enum class TileStatus { kOk, kAbsent, kCorrupt };

struct TileRead {
  TileStatus status = TileStatus::kAbsent;
  cv::Mat pixels;       ///< CV_8UC1, tile_size square, when kOk
  std::string problem;  ///< names the tile, when kCorrupt
};

/// Outcome of reading one tile as stored: its PNG, CRC-checked but not decoded (to pass on
/// unchanged, e.g. to a browser).
struct EncodedTileRead {
  TileStatus status = TileStatus::kAbsent;
  std::vector<unsigned char> png;  ///< when kOk
  std::string problem;             ///< names the tile, when kCorrupt
};

/// One cell of the place index (design.md section 4): the index's records over one tile of
/// its level, as the tracking module encodes them; the store keeps them with their CRC32.
struct PlaceCell {
  std::int64_t col = 0;
  std::int64_t row = 0;
  std::vector<unsigned char> data;
};

/// What the map's place index is, read from its metadata without loading its cells.
struct PlaceIndexInfo {
  int format_version = 0;
  std::string method;  ///< how the records were made (e.g. "orb256"), for the reader to check
  int level = 0;       ///< the map level the records describe
  std::int64_t cells = 0;
  std::int64_t bytes = 0;  ///< of the cells' data
  /// The floor's self-test over the index (runtime::TestFloorRepeats), when it was run on this
  /// index: views of the map searched for everywhere, found at their own place, found (or
  /// ambiguous) elsewhere too. -1 when not run.
  std::int64_t repeat_test_views = -1;
  std::int64_t repeat_test_own = -1;
  std::int64_t repeat_test_elsewhere = -1;
};

/// One cell of the map's quality layer (design.md section 4): what a fix can expect over the
/// floor of one tile of the layer's level, computed when the map is built
/// (tracking::AssessMapQuality) and kept with a CRC32 per cell.
struct QualityCell {
  std::int64_t col = 0;
  std::int64_t row = 0;
  float mapped = 0.0f;     ///< share of the cell's floor that is mapped, 0..1
  float texture = 0.0f;    ///< the texture a template there has (structure tensor's smaller eigenvalue, median); -1: not judged
  float ambiguity = 0.0f;  ///< the best ZNCC of the cell's floor elsewhere nearby (1: a copy); -1: not judged
};

/// When a cell's expected fixes are weak, and why: too little texture for a template
/// (`min_texture`, twice the tracker's default TemplateOptions::min_texture), or floor that
/// matches elsewhere nearly as well as in its place (`max_ambiguity`). Empty: not weak.
struct QualityThresholds {
  double min_texture = 4.0;
  double max_ambiguity = 0.85;
  double min_mapped = 0.25;  ///< cells less mapped than this are a lane's edge, not judged
};
std::string WeakBecause(const QualityCell& cell, const QualityThresholds& thresholds);

struct QualityInfo {
  int level = 0;  ///< the map level whose tiles the cells are
  std::int64_t cells = 0;
};

/// A tile to write: CV_8UC1, tile_size square.
struct TileWrite {
  TileKey key;
  cv::Mat pixels;
};

/// One recorded change of the map's floor (design.md section 4, the map's history): automatic
/// mapping's stretches and automatic map updates are written so, keeping the level-0 tiles
/// they replaced, and `map revert` undoes one.
struct MapUpdate {
  std::int64_t id = 0;      ///< 1, 2, ... in the order written
  std::string time;         ///< when it was written, UTC, ISO 8601 (2026-12-05T03:12:45Z)
  std::string reason;       ///< what wrote it and why, one line
  std::int64_t tiles = 0;   ///< level-0 tiles it replaced or added
  std::string reverted;     ///< when it was undone (UTC, ISO 8601); empty while in force
};

/// A level-0 tile as an update found it: its pixels, or none when it was not there.
struct ReplacedTile {
  TileKey key;
  std::optional<cv::Mat> pixels;
};

/// The map file (design.md section 4): one SQLite database with a metadata table and a
/// tiles table of lossless 8-bit PNGs with their CRC32. Written in WAL mode, every change in
/// one transaction, so a crash or power cut leaves each tile either old or new.
/// Thread-safe. Writes and queries go through one connection guarded by a mutex. Tile reads
/// each take a read-only connection of their own from a pool (opened on first need, one per
/// concurrent reader, each with its statement prepared once), so readers on several threads
/// wait on the disk in parallel instead of queueing behind one slow read; WAL lets them read
/// while a write is in progress, each seeing the last committed state. PNG coding happens
/// outside every lock.
class TileStore {
 public:
  /// Creates a new, empty map file; throws core::Error if it exists or cannot be created.
  static std::unique_ptr<TileStore> Create(const std::filesystem::path& file, const MapGrid& grid);
  /// Opens an existing map; checks format_version and every metadata key, and throws
  /// core::Error (invalid input) naming the file and key when something is wrong.
  static std::unique_ptr<TileStore> Open(const std::filesystem::path& file, bool writable);
  ~TileStore();
  TileStore(const TileStore&) = delete;
  TileStore& operator=(const TileStore&) = delete;

  const MapGrid& grid() const { return grid_; }
  const std::filesystem::path& file() const { return file_; }

  /// Reads and verifies a tile (CRC, PNG decode, size, type). Never throws for a bad tile.
  /// A `buffer` of the tile's size and type is decoded into rather than allocating.
  TileRead Read(const TileKey& key, cv::Mat buffer = cv::Mat()) const;
  /// Reads and CRC-checks a tile's PNG without decoding it. Never throws for a bad tile.
  EncodedTileRead ReadEncoded(const TileKey& key) const;
  /// Writes tiles in one transaction (all or none). Throws core::Error on failure.
  void Write(const std::vector<TileWrite>& tiles);
  /// Write() recorded in the map's history as one update (MapUpdate): the level-0 tiles it
  /// replaces (or that they were absent) are kept with it, in the same one transaction. Returns
  /// the update's id. Throws core::Error on failure, and for an empty `reason`.
  std::int64_t WriteRecorded(const std::vector<TileWrite>& tiles, const std::string& reason);
  /// The map's recorded updates, oldest first (none for a map never updated so).
  std::vector<MapUpdate> History() const;
  /// The level-0 tiles update `id` replaced, as they were before it, each checked against its
  /// CRC32. Throws core::Error (invalid input) naming the map and update when there is no such
  /// update, and naming the tile when a kept one is damaged.
  std::vector<ReplacedTile> Replaced(std::int64_t id) const;
  /// Which level-0 tiles each update replaced or added, as (update id, tile), by id (for
  /// drawing the history; none for a map never updated so).
  std::vector<std::pair<std::int64_t, TileKey>> UpdatedTiles() const;
  /// Changes whenever another connection (another process, or another store open on the same
  /// file) has committed to the map since the last call (SQLite's data_version): a reader's cue
  /// to read what it keeps again.
  std::int64_t DataVersion() const;
  /// Undoes update `id` in one transaction: writes `tiles`, removes `removed` and marks the
  /// update reverted now (mosaic::RevertUpdate computes them). Throws core::Error when the
  /// update is not in force.
  void WriteRevert(std::int64_t id, const std::vector<TileWrite>& tiles, const std::vector<TileKey>& removed);

  /// Every tile of a level (all levels when level < 0), ordered by level, row, col.
  std::vector<TileKey> List(int level = -1) const;
  std::int64_t Count(int level = -1) const;

  /// The place index, when the map has one (an older map has none: nullopt). Throws
  /// core::Error naming the file when its metadata is damaged.
  std::optional<PlaceIndexInfo> Places() const;
  /// Every cell of the place index, each checked against its CRC32. Throws core::Error naming
  /// the file and cell when one is damaged, and when the map has no index.
  std::vector<PlaceCell> ReadPlaces() const;
  /// Replaces the whole place index (table and metadata) in one transaction: a crash leaves
  /// the old index or the new one. Throws core::Error on failure.
  void WritePlaces(const PlaceIndexInfo& info, const std::vector<PlaceCell>& cells);
  /// Records the floor's self-test over the index (PlaceIndexInfo::repeat_test_*); WritePlaces
  /// forgets it, since a new index is of a floor that may have changed.
  void WritePlaceRepeatTest(std::int64_t views, std::int64_t own, std::int64_t elsewhere);

  /// The quality layer, when the map has one (nullopt otherwise). Throws core::Error naming
  /// the file when its metadata is damaged.
  std::optional<QualityInfo> Quality() const;
  /// Every cell of the quality layer, each checked against its CRC32; throws core::Error naming
  /// the file and cell when one is damaged, and when the map has none.
  std::vector<QualityCell> ReadQuality() const;
  /// Replaces the quality layer (cells are tiles of `level`) in one transaction.
  void WriteQuality(int level, const std::vector<QualityCell>& cells);
  /// Copies every committed write from the write-ahead log into the map file itself, empties
  /// the log and leaves WAL mode, so that the file alone holds the map (before it is moved or
  /// copied) and readers open it without creating files beside it; the next writable Open
  /// returns to WAL. Throws core::Error if a reader keeps it from completing.
  void Checkpoint();

  /// zlib level (0-9) of the tiles Write encodes from now on; throws core::Error (invalid
  /// input) outside 0-9. Not thread-safe against a concurrent Write.
  void SetPngCompression(int level);
  int png_compression() const { return png_compression_; }

  /// PNG-encodes a tile at a zlib level (0-9), as stored. Thread-safe.
  static std::vector<unsigned char> Encode(const cv::Mat& pixels, int png_compression = kDefaultTilePngCompression);
  /// Decodes a tile's PNG into `pixels` (reusing its memory when it fits): empty on success,
  /// else what is wrong with it. Checks format and size, not the CRC32.
  static std::string Decode(const std::vector<unsigned char>& png, int tile_size_px, cv::Mat& pixels);
  static std::uint32_t Crc32(const std::vector<unsigned char>& data);

 private:
  TileStore(std::filesystem::path file, sqlite3* db, MapGrid grid);
  void Execute(const std::string& sql) const;
  // PNG-encodes tiles to write, checking their size and type.
  std::vector<std::vector<unsigned char>> EncodeAll(const std::vector<TileWrite>& tiles) const;
  // Inserts (or replaces) encoded tiles; inside a transaction the caller holds.
  void Insert(const std::vector<TileWrite>& tiles, const std::vector<std::vector<unsigned char>>& encoded);
  // Finds a tile's row, checks its CRC and hands the blob to `use` (which returns a problem,
  // or nothing); kCorrupt with `problem` naming the tile when anything fails.
  TileStatus Fetch(const TileKey& key, const std::function<std::string(const unsigned char*, std::size_t)>& use,
                   std::string* problem) const;

  struct Reader;
  struct ReaderDeleter {
    void operator()(Reader* reader) const;
  };
  using ReaderPtr = std::unique_ptr<Reader, ReaderDeleter>;
  /// An idle read connection, or a new one; nullptr (with the reason) when none can be opened.
  ReaderPtr TakeReader(std::string* why) const;
  void GiveBack(ReaderPtr reader) const;

  std::filesystem::path file_;
  sqlite3* db_ = nullptr;
  MapGrid grid_;
  int png_compression_ = kDefaultTilePngCompression;
  mutable std::mutex mutex_;
  mutable std::mutex readers_mutex_;
  mutable std::vector<ReaderPtr> idle_readers_;
};

}  // namespace mosaicloc::mosaic
