#pragma once
// How the process's heap treats freed memory.
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <mutex>

namespace pg {

// Keeps freed blocks of up to 32 MB, and up to 256 MB of free memory at the heap's top, in the
// heap for reuse instead of giving them back to the kernel: glibc's defaults map a block of a few
// MB on its own and unmap it when it is freed, and trim the heap's top past 128 kB at first. A
// loop that allocates and frees the same image-sized buffers or tensors every frame then reuses
// them, where it faulted every page in again each time (docs/learned_normals.md, "Freed memory
// kept"; docs/renderer.md, "Speed"). Once per process; a no-op without glibc.
inline void keep_freed_memory() {
#ifdef __GLIBC__
  static std::once_flag once;
  std::call_once(once, [] {
    mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest on 64-bit
    mallopt(M_TRIM_THRESHOLD, 256 << 20);
  });
#endif
}

}  // namespace pg
