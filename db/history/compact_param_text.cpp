#include "db/history/compact_param_text.hpp"

#include <charconv>
#include <cmath>

namespace imucal::db::history {

namespace {

/// A cursor over the text; every step returns false on the first unexpected character.
class Scanner {
 public:
  Scanner(std::string_view text, bool non_negative) : s_(text), non_negative_(non_negative) {}

  bool eat(char c) {
    if (i_ >= s_.size() || s_[i_] != c) return false;
    ++i_;
    return true;
  }
  bool at_end() const { return i_ == s_.size(); }

  /// A key without escapes: "name".
  bool key(std::string_view& name) {
    if (!eat('"')) return false;
    const std::size_t end = s_.find('"', i_);
    if (end == std::string_view::npos) return false;
    name = s_.substr(i_, end - i_);
    if (name.find('\\') != std::string_view::npos) return false;
    i_ = end + 1;
    return eat(':');
  }

  /// A JSON number (RFC 8259 grammar checked here: std::from_chars alone would also take "inf",
  /// "nan", "01" or "1."), finite, and non-negative when asked.
  bool number(double& v) {
    const std::size_t start = i_;
    if (i_ < s_.size() && s_[i_] == '-') ++i_;
    if (i_ >= s_.size()) return false;
    if (s_[i_] == '0') {
      ++i_;
    } else if (!digits()) {
      return false;
    }
    if (i_ < s_.size() && s_[i_] == '.') {
      ++i_;
      if (!digits()) return false;
    }
    if (i_ < s_.size() && (s_[i_] == 'e' || s_[i_] == 'E')) {
      ++i_;
      if (i_ < s_.size() && (s_[i_] == '+' || s_[i_] == '-')) ++i_;
      if (!digits()) return false;
    }
    const auto r = std::from_chars(s_.data() + start, s_.data() + i_, v);
    if (r.ec != std::errc() || r.ptr != s_.data() + i_) return false;
    return std::isfinite(v) && !(non_negative_ && v < 0.0);
  }

  /// [a,b,c] into out[0], out[stride], out[2*stride].
  bool triple(double* out, int stride) {
    return eat('[') && number(out[0]) && eat(',') && number(out[stride]) && eat(',') &&
           number(out[2 * stride]) && eat(']');
  }

  bool vector3(Eigen::Vector3d& v) { return triple(v.data(), 1); }

  /// [[row 0],[row 1],[row 2]] (Eigen stores column-major: a row's entries are 3 apart).
  bool matrix3(Eigen::Matrix3d& m) {
    return eat('[') && triple(&m(0, 0), 3) && eat(',') && triple(&m(1, 0), 3) && eat(',') &&
           triple(&m(2, 0), 3) && eat(']');
  }

 private:
  bool digits() {
    const std::size_t start = i_;
    while (i_ < s_.size() && s_[i_] >= '0' && s_[i_] <= '9') ++i_;
    return i_ > start;
  }

  std::string_view s_;
  bool non_negative_;
  std::size_t i_ = 0;
};

}  // namespace

bool read_compact_param_set(std::string_view text, bool non_negative, calib::core::ParamSet& out) {
  Scanner s(text, non_negative);
  if (!s.eat('{')) return false;
  unsigned seen = 0;
  for (int k = 0; k < 5; ++k) {
    if (k > 0 && !s.eat(',')) return false;
    std::string_view name;
    if (!s.key(name)) return false;
    unsigned bit = 0;
    bool ok = false;
    if (name == "accel_M") {
      bit = 1u, ok = s.matrix3(out.accel_M);
    } else if (name == "accel_bias_mps2") {
      bit = 2u, ok = s.vector3(out.accel_bias_mps2);
    } else if (name == "gyro_M") {
      bit = 4u, ok = s.matrix3(out.gyro_M);
    } else if (name == "gyro_bias_radps") {
      bit = 8u, ok = s.vector3(out.gyro_bias_radps);
    } else if (name == "table_misalignment_rad") {
      bit = 16u, ok = s.vector3(out.table_misalignment_rad);
    }
    if (!ok || (seen & bit) != 0) return false;
    seen |= bit;
  }
  return s.eat('}') && s.at_end() && seen == 31u;
}

}  // namespace imucal::db::history
