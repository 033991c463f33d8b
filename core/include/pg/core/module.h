#pragma once
// Libraries that a program loads only when a command needs them: OpenImageIO's codecs
// (src/image_codec.h) and FFmpeg's video decoders (tools/patchgraph/video.h). Each sits in a
// module built beside the programs, with one exported function.
#include <string>

namespace pg {

// The exported function `entry` of the module built at `built_path`, loaded on this call (a
// module loaded before is not loaded again). In a build tree that moved, the module of that name
// in the folder named as its build folder beside this program's folder is taken instead
// (build/tools/tacsim, build/tests/test_core -> build/core/). Throws std::runtime_error naming
// `what` and the reasons when neither loads.
void* module_entry(const std::string& built_path, const char* entry, const std::string& what);

}  // namespace pg
