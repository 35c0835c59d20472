// strata::Error: every user-facing failure (bad file, bad option, bad input arrays, device fault)
// is reported as an Error whose message is one line naming the file or the call and the problem.
#pragma once

#include <stdexcept>
#include <string>

namespace strata {

class Error : public std::runtime_error {
 public:
  explicit Error(const char* what) : std::runtime_error(what) {}
  explicit Error(const std::string& what) : std::runtime_error(withoutNul(what)) {}

 private:
  // what() is a C string: a NUL byte quoted from an input (a name inside a file) would cut the
  // message short before the problem is stated, so it is shown as \x00.
  static std::string withoutNul(const std::string& text) {
    if (text.find('\0') == std::string::npos) return text;
    std::string out;
    for (char c : text) c == '\0' ? out += "\\x00" : out += c;
    return out;
  }
};

// Memory that could not be had, host or device: the message names what did not fit.
class OutOfMemory : public Error {
 public:
  using Error::Error;
};

// The OpenCL device or its driver failed, not the input: no device, a missing extension, a
// program that does not build, a call that fails, a buffer past the device's largest allocation.
class DeviceError : public Error {
 public:
  using Error::Error;
};

}  // namespace strata
