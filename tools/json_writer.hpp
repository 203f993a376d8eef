#pragma once
// A minimal JSON object writer for the CLI's --json output (one object, flat or nested).

#include <cmath>
#include <cstdint>
#include <span>
#include <sstream>
#include <string>
#include <vector>

namespace volpar {

class JsonWriter {
 public:
  JsonWriter() { out_.precision(17); }

  JsonWriter& begin() { return open('{'); }
  JsonWriter& begin(const std::string& key) { return this->key(key).open('{'); }
  JsonWriter& end() {
    out_ << '}';
    first_ = false;
    return *this;
  }
  JsonWriter& field(const std::string& k, const std::string& v) {
    key(k);
    quote(v);
    return *this;
  }
  JsonWriter& field(const std::string& k, const char* v) { return field(k, std::string(v)); }
  JsonWriter& field(const std::string& k, double v) {
    key(k);
    if (std::isfinite(v)) out_ << v;
    else out_ << "null";
    return *this;
  }
  JsonWriter& field(const std::string& k, std::int64_t v) {
    key(k);
    out_ << v;
    return *this;
  }
  JsonWriter& field(const std::string& k, std::size_t v) { return field(k, static_cast<std::int64_t>(v)); }
  JsonWriter& field(const std::string& k, int v) { return field(k, static_cast<std::int64_t>(v)); }
  JsonWriter& field(const std::string& k, bool v) {
    key(k);
    out_ << (v ? "true" : "false");
    return *this;
  }
  JsonWriter& field(const std::string& k, const std::vector<std::string>& v) {
    key(k);
    out_ << '[';
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i) out_ << ", ";
      quote(v[i]);
    }
    out_ << ']';
    return *this;
  }
  JsonWriter& field(const std::string& k, std::span<const std::size_t> v) {
    key(k);
    out_ << '[';
    for (std::size_t i = 0; i < v.size(); ++i) out_ << (i ? ", " : "") << v[i];
    out_ << ']';
    return *this;
  }
  JsonWriter& field(const std::string& k, std::span<const double> v) {
    key(k);
    out_ << '[';
    for (std::size_t i = 0; i < v.size(); ++i) {
      out_ << (i ? ", " : "");
      if (std::isfinite(v[i])) out_ << v[i];
      else out_ << "null";
    }
    out_ << ']';
    return *this;
  }
  [[nodiscard]] std::string str() const { return out_.str(); }

 private:
  JsonWriter& open(char c) {
    out_ << c;
    first_ = true;
    return *this;
  }
  JsonWriter& key(const std::string& k) {
    if (!first_) out_ << ", ";
    first_ = false;
    quote(k);
    out_ << ": ";
    return *this;
  }
  void quote(const std::string& s) {
    out_ << '"';
    for (const unsigned char c : s) {
      switch (c) {
        case '"': out_ << "\\\""; break;
        case '\\': out_ << "\\\\"; break;
        case '\n': out_ << "\\n"; break;
        case '\r': out_ << "\\r"; break;
        case '\t': out_ << "\\t"; break;
        default:
          if (c < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\u%04x", c);
            out_ << buf;
          } else {
            out_ << c;
          }
      }
    }
    out_ << '"';
  }

  std::ostringstream out_;
  bool first_ = true;
};

}  // namespace volpar
