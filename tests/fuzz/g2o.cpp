// A pose graph in g2o's text format (mapping::ReadG2o, `map poses --graph-in`), and the
// solve that follows it: whatever a file says, the solver gets finite poses and information
// matrices it can use, or the file is refused.
#include <cmath>

#include "fuzz_input.hpp"
#include "mosaicloc/mapping/pose_graph.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path file = mosaicloc::fuzz::ScratchDir() / "graph.g2o";
  mosaicloc::fuzz::WriteBytes(file, data, size);
  mosaicloc::fuzz::ExpectOnlyCoreErrors([&] {
    mosaicloc::mapping::PoseGraph graph = mosaicloc::mapping::ReadG2o(file);
    for (const auto& node : graph.nodes) {
      if (!std::isfinite(node.x_mm()) || !std::isfinite(node.y_mm()) || !std::isfinite(node.yaw_rad())) {
        __builtin_trap();  // the reader lets no non-finite pose through
      }
    }
    if (graph.nodes.size() <= 64 && graph.edges.size() <= 256) {
      mosaicloc::mapping::OptimizeOptions options;
      options.max_iterations = 5;
      mosaicloc::mapping::Optimize(graph, options);
    }
  });
  return 0;
}
