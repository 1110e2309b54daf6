#include "db/history/export_row_writer.hpp"

#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>

#include "db/history/export.hpp"

namespace imucal::db::history {

namespace {

using nlohmann::json;

void append_null(std::string& out) { out += "null"; }

void append_bool(std::string& out, bool v) { out += v ? "true" : "false"; }

void append_int(std::string& out, long long v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, static_cast<size_t>(r.ptr - buf));
}

/// nlohmann's dump of a double: its own shortest round-trip formatter (Grisu2), null when not
/// finite. (detail::to_chars is the function its serializer calls; the test pins the output.)
void append_double(std::string& out, double v) {
  if (!std::isfinite(v)) return append_null(out);
  char buf[64];
  char* end = nlohmann::detail::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, static_cast<size_t>(end - buf));
}

/// Printable ASCII without '"' and '\\' needs no escaping; anything else goes through nlohmann
/// (control characters, UTF-8 validation).
void append_string(std::string& out, const std::string& s) {
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u >= 0x7f || c == '"' || c == '\\') {
      out += json(s).dump();
      return;
    }
  }
  out += '"';
  out += s;
  out += '"';
}

/// `{"a":…,"b":…}` with the keys given in nlohmann's (sorted) order.
class Object {
 public:
  explicit Object(std::string& out) : out_(out) { out_ += '{'; }
  ~Object() { out_ += '}'; }
  Object(const Object&) = delete;
  Object& operator=(const Object&) = delete;
  std::string& key(const char* k) {
    if (!first_) out_ += ',';
    first_ = false;
    out_ += '"';
    out_ += k;
    out_ += "\":";
    return out_;
  }

 private:
  std::string& out_;
  bool first_ = true;
};

void append_vec(std::string& out, const Eigen::Vector3d& v) {
  out += '[';
  for (int i = 0; i < 3; ++i) {
    if (i) out += ',';
    append_double(out, v(i));
  }
  out += ']';
}

void append_mat(std::string& out, const Eigen::Matrix3d& m) {
  out += '[';
  for (int r = 0; r < 3; ++r) {
    if (r) out += ',';
    append_vec(out, m.row(r).transpose());
  }
  out += ']';
}

void append_param_fields(Object& o, const calib::core::ParamSet& p) {
  append_mat(o.key("accel_M"), p.accel_M);
  append_vec(o.key("accel_bias_mps2"), p.accel_bias_mps2);
  append_mat(o.key("gyro_M"), p.gyro_M);
  append_vec(o.key("gyro_bias_radps"), p.gyro_bias_radps);
}

/// db::archive::param_set_to_json(params, &sigma); a set it refuses (not finite, negative σ) is
/// handed to it so that the error is its own.
void append_params(std::string& out, const CalibrationRecord& c) {
  const calib::core::ParamVector p = c.params.to_vector(), s = c.sigma.to_vector();
  if (!p.allFinite() || !s.allFinite() || (s.array() < 0.0).any()) {
    out += calibration_json(c).at("params").dump();  // throws Corrupt naming the field
    return;
  }
  Object o(out);
  append_param_fields(o, c.params);
  {
    Object sigma(o.key("sigma"));
    append_param_fields(sigma, c.sigma);
    append_vec(sigma.key("table_misalignment_rad"), c.sigma.table_misalignment_rad);
  }
  append_vec(o.key("table_misalignment_rad"), c.params.table_misalignment_rad);
}

void append_metrics(std::string& out, const StoredMetrics& m) {
  Object o(out);
  append_double(o.key("accel_rmse_ug"), m.accel_rmse_ug);
  append_vec(o.key("body_misalignment_theta_bp_rad"), m.body_misalignment_theta_bp_rad);
  append_double(o.key("heading_offset_gamma_np_rad"), m.heading_offset_gamma_np_rad);
  append_double(o.key("orientation_rmse_mdeg"), m.orientation_rmse_mdeg);
}

void append_strings(std::string& out, const std::vector<std::string>& v) {
  out += '[';
  for (size_t i = 0; i < v.size(); ++i) {
    if (i) out += ',';
    append_string(out, v[i]);
  }
  out += ']';
}

void append_calibration(std::string& out, const CalibrationRecord& c) {
  Object o(out);
  append_string(o.key("body_frame"), to_string(c.body_frame));
  append_bool(o.key("converged"), c.converged);
  append_int(o.key("iterations"), c.iterations);
  append_string(o.key("method"), to_string(c.method));
  c.metrics ? append_metrics(o.key("metrics"), *c.metrics) : append_null(o.key("metrics"));
  append_strings(o.key("notes"), c.notes);
  append_params(o.key("params"), c);
  append_double(o.key("runtime_s"), c.runtime_s);
  append_strings(o.key("unobservable"), c.unobservable);
  append_strings(o.key("warnings"), c.warnings);
}

void append_crosscheck(std::string& out, const CrosscheckRecord& x) {
  Object o(out);
  std::string& f = o.key("failures");
  f += '[';
  for (size_t i = 0; i < x.failures.size(); ++i) {
    if (i) f += ',';
    Object failure(f);
    append_string(failure.key("detail"), x.failures[i].detail);
    append_string(failure.key("term"), x.failures[i].term);
  }
  f += ']';
  append_double(o.key("k_sigma"), x.k_sigma);
  append_strings(o.key("not_compared"), x.not_compared);
  append_string(o.key("verdict"), to_string(x.verdict));
}

/// The run's reasons as run_json prints them: [{"source", "text"}, ...].
void append_reasons(std::string& out, const std::vector<RunReason>& reasons) {
  out += '[';
  for (size_t i = 0; i < reasons.size(); ++i) {
    if (i) out += ',';
    Object reason(out);
    append_string(reason.key("source"), reasons[i].source);
    append_string(reason.key("text"), reasons[i].text);
  }
  out += ']';
}

/// A stored JSON-object column as run_json prints it: null when empty, Corrupt when damaged.
void append_stored_object(std::string& out, const std::string& text, RunId run_id,
                          const char* column) {
  if (text.empty()) return append_null(out);
  const json parsed = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!parsed.is_object())
    throw Corrupt("run " + std::to_string(run_id) + ": stored " + column + " is not a JSON object");
  out += parsed.dump();
}

template <typename T, typename Append>
void append_optional(std::string& out, const std::optional<T>& v, Append append) {
  v ? append(out, *v) : append_null(out);
}

}  // namespace

void append_export_row_json(std::string& out, const ExportRow& row) {
  const RunRecord& r = row.run;
  const auto time_utc = [](std::string& s, TimestampMs t) { append_string(s, format_time_utc(t)); };
  const auto integer = [](std::string& s, long long v) { append_int(s, v); };
  Object o(out);
  append_string(o.key("archive_path"), r.archive_path);
  append_string(o.key("archive_sha256"), r.archive_sha256);
  append_optional(o.key("calibration"), row.calibration, append_calibration);
  append_stored_object(o.key("capture"), r.capture_json, r.run_id, "capture_json");
  append_optional(o.key("crosscheck"), row.crosscheck, append_crosscheck);
  append_optional(o.key("crosscheck_verdict"), r.crosscheck_verdict,
                  [](std::string& s, Verdict v) { append_string(s, to_string(v)); });
  append_stored_object(o.key("diagnosis"), r.diagnosis_json, r.run_id, "diagnosis_json");
  append_optional(o.key("ended_at"), r.ended_at_ms, time_utc);
  append_optional(o.key("ended_at_ms"), r.ended_at_ms, integer);
  append_string(o.key("failure_reason"), r.failure_reason);
  append_string(o.key("holding_method"), to_string(r.holding_method));
  append_string(o.key("holding_reason"), r.holding_reason);
  append_string(o.key("operator"), r.operator_name);
  append_string(o.key("origin"), r.origin);
  append_optional(o.key("outcome_of"), r.verdict,
                  [&r](std::string& s, RunVerdict) { append_string(s, outcome_of(r)); });
  append_string(o.key("promote_reason"), r.promote_reason);
  append_optional(o.key("promoted_at"), r.promoted_at_ms, time_utc);
  append_string(o.key("promoted_by"), r.promoted_by);
  append_reasons(o.key("reasons"), r.reasons);
  append_optional(o.key("reprocessed_from"), r.reprocessed_from, integer);
  append_int(o.key("run_id"), r.run_id);
  append_string(o.key("sequence_name"), r.sequence_name);
  append_string(o.key("sequence_sha256"), r.sequence_sha256);
  append_string(o.key("serial"), r.serial);
  append_string(o.key("setting"), calib::core::setting_name(r.setting));
  append_string(o.key("slot"), r.slot);
  append_string(o.key("software_version"), r.software_version);
  time_utc(o.key("started_at"), r.started_at_ms);
  append_int(o.key("started_at_ms"), r.started_at_ms);
  append_string(o.key("state"), to_string(r.state));
  append_string(o.key("station"), r.station);
  append_optional(o.key("table_run"), r.table_run_id, integer);
  append_optional(o.key("verdict"), r.verdict,
                  [](std::string& s, RunVerdict v) { append_string(s, to_string(v)); });
}

}  // namespace imucal::db::history
