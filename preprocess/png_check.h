// Integrity checks of PNG data before it is handed to OpenImageIO. Its PNG reader leaves libpng's
// default error handler in place, which prints its own "libpng error: ..." line on stderr for a
// truncated or damaged file; checked first, such a file gets strata's one-line error alone.
#pragma once

#include <cstddef>
#include <string>

namespace strata {

// True when the data starts with the PNG signature.
bool isPng(const unsigned char* data, size_t size);

// Why PNG data is damaged, or "" when its header, chunk structure, CRCs and zlib image stream are
// whole (what the decoder checks beyond that stays with it). Messages say "truncated PNG image"
// or "corrupt PNG image" and the detail.
std::string pngDamage(const unsigned char* data, size_t size);

// The same for a file: "" when it is not a PNG, is larger than 1 GiB (left to the decoder) or
// is whole.
std::string pngFileDamage(const std::string& path);

}  // namespace strata
