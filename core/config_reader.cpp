#include "config_reader.h"

#include <cmath>
#include <set>
#include <sstream>
#include <vector>

namespace sphray {

using nlohmann::json;

ConfigReader::ConfigReader(const json& j, std::string file, std::string path)
    : j_(j), file_(std::move(file)), path_(std::move(path)) {
  if (!j_.is_object()) fail("", j_, "must be an object");
}

void ConfigReader::fail(const std::string& key, const json& value, const std::string& why) const {
  std::ostringstream os;
  os << file_ << ": " << (key.empty() ? (path_.empty() ? std::string("scene") : path_) : full(key));
  if (!value.is_null() || !key.empty()) os << " = " << value.dump();
  os << ": " << why;
  throw SceneError(os.str());
}

void ConfigReader::only(std::initializer_list<const char*> keys) const {
  std::set<std::string> allowed(keys.begin(), keys.end());
  for (auto it = j_.begin(); it != j_.end(); ++it) {
    if (!allowed.count(it.key())) {
      std::string list;
      for (auto& k : allowed) list += (list.empty() ? "" : ", ") + k;
      fail(it.key(), it.value(), "unknown key (allowed here: " + list + ")");
    }
  }
}

double ConfigReader::number(const std::string& key, double def, double lo, double hi, bool required,
                            bool lo_open) const {
  if (!has(key)) {
    if (required) fail(key, json(), "is required");
    return def;
  }
  const json& v = at(key);
  if (!v.is_number()) fail(key, v, "must be a number");
  const double x = v.get<double>();
  if (!std::isfinite(x)) fail(key, v, "must be finite");
  if (x < lo || (lo_open && x == lo) || x > hi) {
    std::ostringstream os;
    os << "must be in " << (lo_open ? "(" : "[") << lo << ", " << hi << "]";
    fail(key, v, os.str());
  }
  return x;
}

int ConfigReader::integer(const std::string& key, int def, int lo, int hi) const {
  const double v = number(key, def, lo, hi);
  if (v != std::floor(v)) fail(key, at(key), "must be an integer");
  return int(v);
}

bool ConfigReader::boolean(const std::string& key, bool def) const {
  if (!has(key)) return def;
  if (!at(key).is_boolean()) fail(key, at(key), "must be true or false");
  return at(key).get<bool>();
}

std::string ConfigReader::string(const std::string& key, const std::string& def,
                                 std::initializer_list<const char*> choices) const {
  if (!has(key)) return def;
  const json& v = at(key);
  std::string list;
  for (auto c : choices) list += std::string(list.empty() ? "" : ", ") + "\"" + c + "\"";
  if (!v.is_string()) fail(key, v, "must be one of " + list);
  const std::string s = v.get<std::string>();
  for (auto c : choices)
    if (s == c) return s;
  fail(key, v, "must be one of " + list);
}

Vec3d ConfigReader::vec3(const std::string& key, Vec3d def, bool required) const {
  if (!has(key)) {
    if (required) fail(key, json(), "is required");
    return def;
  }
  const json& v = at(key);
  if (!v.is_array() || v.size() != 3) fail(key, v, "must be an array of three numbers [x, y, z]");
  double c[3];
  for (int k = 0; k < 3; ++k) {
    if (!v[k].is_number()) fail(key, v, "must be an array of three numbers [x, y, z]");
    c[k] = v[k].get<double>();
    if (!std::isfinite(c[k])) fail(key, v, "must be finite");
  }
  return {c[0], c[1], c[2]};
}

ConfigReader ConfigReader::child(const std::string& key) const {
  static const json empty = json::object();
  return ConfigReader(has(key) ? at(key) : empty, file_, full(key));
}

json parse_json_checked(const std::string& text, std::string& repeated, bool allow_exceptions) {
  struct Level {
    bool array;
    size_t index = 0;  // arrays: the element being read
    std::string key;   // objects: the key being read
    std::set<std::string> keys;
  };
  std::vector<Level> levels;
  auto dotted = [&] {
    std::string path;
    for (const Level& l : levels) path += (path.empty() ? "" : ".") + (l.array ? std::to_string(l.index) : l.key);
    return path;
  };
  auto element_done = [&] {
    if (!levels.empty() && levels.back().array) ++levels.back().index;
  };
  const json::parser_callback_t check = [&](int, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start: levels.push_back(Level{false, 0, {}, {}}); break;
      case json::parse_event_t::array_start: levels.push_back(Level{true, 0, {}, {}}); break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        levels.pop_back();
        element_done();
        break;
      case json::parse_event_t::key:
        levels.back().key = parsed.get<std::string>();
        if (!levels.back().keys.insert(levels.back().key).second && repeated.empty()) repeated = dotted();
        break;
      case json::parse_event_t::value: element_done(); break;
    }
    return true;
  };
  return json::parse(text, check, allow_exceptions);
}

}  // namespace sphray
