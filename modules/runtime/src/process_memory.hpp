#pragma once

#include <malloc.h>
#include <unistd.h>

#include <fstream>

namespace mosaicloc::runtime {

/// What the process holds, MiB: resident in RAM, and of the heap in use (mapped chunks
/// included). Resident memory beyond the heap in use is code, stacks, mapped files and what the
/// allocator keeps of freed memory.
struct ProcessMemory {
  double rss_mib = 0.0;
  double heap_mib = 0.0;
};

/// From /proc/self/statm and glibc's mallinfo2, which takes every arena's lock in turn and walks
/// its free lists: read it seconds apart, never per frame. Under AddressSanitizer the heap reads
/// near 0 (its allocator replaces glibc's and does not answer mallinfo2).
inline ProcessMemory ReadProcessMemory() {
  ProcessMemory memory;
  std::ifstream statm("/proc/self/statm");
  long pages_total = 0, pages_resident = 0;
  if (statm >> pages_total >> pages_resident) {
    memory.rss_mib = static_cast<double>(pages_resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / (1 << 20);
  }
  const struct mallinfo2 heap = mallinfo2();
  memory.heap_mib = static_cast<double>(heap.uordblks + heap.hblkhd) / (1 << 20);
  return memory;
}

}  // namespace mosaicloc::runtime
