#pragma once
// Torch writes its archives (model files, checkpoints) as zip files with a CRC-32 per entry, but
// reads them without checking it: bytes damaged in place inside a weight tensor load as other
// weights. This checks every entry's checksum first.
#include <string>

namespace pg::learn {

// Throws InputError naming `path` (and the entry) when an entry's data does not match its
// CRC-32, the zip's directory is damaged, or the file is cut short. `what` names the kind of
// file in the message ("model file", "checkpoint"). A file that is not a zip at all passes: Torch
// says so in its own words.
void check_zip_checksums(const std::string& path, const std::string& what);

}  // namespace pg::learn
