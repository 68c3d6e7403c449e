// The SHA-256 of a text as lowercase hex: what run.json, calibration.json and certificates name files by.
#pragma once
#include <string>
#include <string_view>

namespace fpss {

// Lowercase hex digest of `text`'s bytes (OpenSSL's EVP).
std::string sha256_hex(std::string_view text);

}  // namespace fpss
