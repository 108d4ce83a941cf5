// Reading one section of a scene file: every stage parses and validates its
// own section through a ConfigReader, which names the file and the dotted key
// of every bad value (docs/scenes.md).
#pragma once

#include <initializer_list>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "vec.h"

namespace sphray {

// A bad scene value: the message names file, key and value (exit code 2).
struct SceneError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class ConfigReader {
 public:
  using json = nlohmann::json;
  // `j` must outlive the reader; `path` is its dotted key ("" for the root).
  ConfigReader(const json& j, std::string file, std::string path);

  [[noreturn]] void fail(const std::string& key, const json& value, const std::string& why) const;
  std::string full(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  bool has(const std::string& key) const { return j_.contains(key); }
  const json& at(const std::string& key) const { return j_.at(key); }
  const std::string& file() const { return file_; }

  // Refuses any key not in `keys`, listing those allowed.
  void only(std::initializer_list<const char*> keys) const;
  // A number in [lo, hi] ((lo, hi] with lo_open); `def` when the key is absent.
  double number(const std::string& key, double def, double lo, double hi, bool required = false,
                bool lo_open = false) const;
  // An integer in [lo, hi].
  int integer(const std::string& key, int def, int lo, int hi) const;
  bool boolean(const std::string& key, bool def) const;
  std::string string(const std::string& key, const std::string& def, std::initializer_list<const char*> choices) const;
  Vec3d vec3(const std::string& key, Vec3d def, bool required = false) const;
  // The object at `key` (an empty one when absent).
  ConfigReader child(const std::string& key) const;

 private:
  const json& j_;
  std::string file_, path_;
};

// JSON text parsed with every object's keys checked for repeats: JSON allows
// them and nlohmann keeps the last, so a scene with two "sph" sections ran
// with the second one silently. Throws json::parse_error as json::parse
// does; returns the dotted key of the first repeat in `repeated`.
nlohmann::json parse_json_checked(const std::string& text, std::string& repeated, bool allow_exceptions = true);

}  // namespace sphray
