#include "db/history/export.hpp"

#include "db/archive/archive_error.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/param_json.hpp"
#include "db/archive/run_archive.hpp"
#include "db/history/export_row_writer.hpp"

namespace imucal::db::history {

using nlohmann::json;

const char* const kCsvRunColumns[24] = {"run_id",
                                        "serial",
                                        "state",
                                        "verdict",
                                        "crosscheck_verdict",
                                        "started_at",
                                        "ended_at",
                                        "operator",
                                        "station",
                                        "sequence_name",
                                        "sequence_sha256",
                                        "software_version",
                                        "archive_path",
                                        "archive_sha256",
                                        "failure_reason",
                                        "reprocessed_from",
                                        "setting",
                                        "origin",
                                        "promoted_at",
                                        "promoted_by",
                                        "promote_reason",
                                        "slot",
                                        "table_run",
                                        "outcome_of"};

const char* const kCsvCalibrationColumns[11] = {"method",         "converged",
                                                "iterations",     "runtime_s",
                                                "warnings",       "orientation_rmse_mdeg",
                                                "accel_rmse_ug",  "heading_offset_gamma_np_rad",
                                                "theta_bp_x_rad", "theta_bp_y_rad",
                                                "theta_bp_z_rad"};

const char* const kCsvCrosscheckColumns[2] = {"crosscheck_k_sigma", "crosscheck_failures"};

const char* const kCsvDiagnosisColumns[11] = {
    "diagnosis.verdict",           "diagnosis.summary",
    "diagnosis.explained_by",      "diagnosis.best.effect",
    "diagnosis.best.magnitude",    "diagnosis.best.sigma",
    "diagnosis.best.unit",         "diagnosis.overall.gap",
    "diagnosis.overall.p_value",   "diagnosis.held_out.gap_before",
    "diagnosis.held_out.gap_after"};

std::string csv_field(const std::string& value) {
  if (value.find_first_of(",\"\r\n") == std::string::npos) return value;
  std::string out = "\"";
  for (char c : value) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

namespace {

void check_stream(std::ostream& out, const char* what) {
  if (!out)
    throw IoError(std::string(what) + ": writing the output failed (disk full or closed pipe?)");
}

class CsvLine {
 public:
  void field(const std::string& v) {
    separator();
    if (v.find_first_of(",\"\r\n") == std::string::npos)
      line_ += v;
    else
      line_ += csv_field(v);
  }
  /// Numbers never need quoting: appended in shortest round-trip form without a temporary.
  void number(double v) {
    separator();
    db::archive::append_double(line_, v);
  }
  void integer(long long v) { field(std::to_string(v)); }
  void empty() { field(std::string()); }
  void separator() {
    if (!first_) line_ += ',';
    first_ = false;
  }
  std::string take() {
    line_ += "\r\n";
    std::string s = std::move(line_);
    line_.clear();
    first_ = true;
    return s;
  }

 private:
  std::string line_;
  bool first_ = true;
};

json params_with_sigma(const CalibrationRecord& c) {
  try {
    return db::archive::param_set_to_json(c.params, &c.sigma);
  } catch (const db::archive::ArchiveError& e) {
    throw Corrupt(std::string("calibration ") + to_string(c.method) + ": " + e.what());
  }
}

/// The run's cross-check and capture counters (the columns after the sigmas).
void crosscheck_and_capture_fields(const ExportRow& row, CsvLine& line) {
  if (row.crosscheck) {
    line.number(row.crosscheck->k_sigma);
    std::string failures;
    for (const auto& f : row.crosscheck->failures)
      failures += (failures.empty() ? "" : "; ") + f.term + ": " + f.detail;
    line.field(failures);
  } else {
    line.empty();
    line.empty();
  }
  json capture;
  if (!row.run.capture_json.empty()) {
    capture = json::parse(row.run.capture_json, nullptr, /*allow_exceptions=*/false);
    if (!capture.is_object())
      throw Corrupt("run " + std::to_string(row.run.run_id) +
                    ": stored capture_json is not a JSON object");
  }
  for (const auto& counter : db::archive::CaptureInfo::counters()) {
    const json* value = capture.is_object() && capture.contains(counter.first)
                            ? &capture.at(counter.first)
                            : nullptr;
    value && value->is_number_integer() ? line.integer(value->get<long long>()) : line.empty();
  }
}

/// The run's stored gap diagnosis summary (what the JSON export's "diagnosis" holds) as
/// kCsvDiagnosisColumns; empty fields where the run has none or a key is absent.
void diagnosis_fields(const RunRecord& run, CsvLine& line) {
  json d;
  if (!run.diagnosis_json.empty()) {
    d = json::parse(run.diagnosis_json, nullptr, /*allow_exceptions=*/false);
    if (!d.is_object())
      throw Corrupt("run " + std::to_string(run.run_id) +
                    ": stored diagnosis_json is not a JSON object");
  }
  const auto at = [&](std::initializer_list<const char*> path) -> const json* {
    const json* j = &d;
    for (const char* k : path) {
      if (!j->is_object() || !j->contains(k)) return nullptr;
      j = &(*j)[k];
    }
    return j;
  };
  const auto text = [&](std::initializer_list<const char*> path) {
    const json* j = at(path);
    j && j->is_string() ? line.field(j->get<std::string>()) : line.empty();
  };
  const auto number = [&](std::initializer_list<const char*> path) {
    const json* j = at(path);
    j && j->is_number() ? line.number(j->get<double>()) : line.empty();
  };
  text({"verdict"});
  text({"summary"});
  std::string set;
  if (const json* e = at({"explained_by"}); e && e->is_array())
    for (const auto& n : *e) set += (set.empty() ? "" : "|") + n.get<std::string>();
  line.field(set);
  text({"best", "effect"});
  number({"best", "magnitude"});
  number({"best", "sigma"});
  text({"best", "unit"});
  number({"overall", "gap"});
  number({"overall", "p_value"});
  number({"held_out", "gap_before"});
  number({"held_out", "gap_after"});
}

}  // namespace

std::size_t export_csv(const Repository& repo, const ExportFilter& filter, std::ostream& out) {
  CsvLine line;
  for (const char* c : kCsvRunColumns) line.field(c);
  for (const char* c : kCsvCalibrationColumns) line.field(c);
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    line.field(calib::core::param_info(i).name);
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    line.field("sigma." + calib::core::param_info(i).name);
  for (const char* c : kCsvCrosscheckColumns) line.field(c);
  for (const auto& counter : db::archive::CaptureInfo::counters())
    line.field(std::string("capture.") + counter.first);
  for (const char* c : kCsvDiagnosisColumns) line.field(c);
  out << line.take();
  check_stream(out, "export csv");
  std::size_t rows = 0;
  repo.export_rows(filter, [&](const ExportRow& row) {
    const RunRecord& r = row.run;
    line.integer(r.run_id);
    line.field(r.serial);
    line.field(to_string(r.state));
    r.verdict ? line.field(to_string(*r.verdict)) : line.empty();
    r.crosscheck_verdict ? line.field(to_string(*r.crosscheck_verdict)) : line.empty();
    line.field(format_time_utc(r.started_at_ms));
    r.ended_at_ms ? line.field(format_time_utc(*r.ended_at_ms)) : line.empty();
    line.field(r.operator_name);
    line.field(r.station);
    line.field(r.sequence_name);
    line.field(r.sequence_sha256);
    line.field(r.software_version);
    line.field(r.archive_path);
    line.field(r.archive_sha256);
    line.field(r.failure_reason);
    r.reprocessed_from ? line.integer(*r.reprocessed_from) : line.empty();
    line.field(calib::core::setting_name(r.setting));
    line.field(r.origin);
    r.promoted_at_ms ? line.field(format_time_utc(*r.promoted_at_ms)) : line.empty();
    line.field(r.promoted_by);
    line.field(r.promote_reason);
    line.field(r.slot);
    r.table_run_id ? line.integer(*r.table_run_id) : line.empty();
    r.verdict ? line.field(outcome_of(r)) : line.empty();
    if (row.calibration) {
      const CalibrationRecord& c = *row.calibration;
      line.field(to_string(c.method));
      line.integer(c.converged ? 1 : 0);
      line.integer(c.iterations);
      line.number(c.runtime_s);
      std::string warnings;
      for (const auto& w : c.warnings) warnings += (warnings.empty() ? "" : "; ") + w;
      line.field(warnings);
      if (c.metrics) {
        line.number(c.metrics->orientation_rmse_mdeg);
        line.number(c.metrics->accel_rmse_ug);
        line.number(c.metrics->heading_offset_gamma_np_rad);
        for (int k = 0; k < 3; ++k) line.number(c.metrics->body_misalignment_theta_bp_rad(k));
      } else {
        for (int k = 0; k < 6; ++k) line.empty();
      }
      const calib::core::ParamVector p = c.params.to_vector(), s = c.sigma.to_vector();
      for (int i = 0; i < calib::core::ParamSet::kSize; ++i) line.number(p(i));
      for (int i = 0; i < calib::core::ParamSet::kSize; ++i) line.number(s(i));
    } else {
      for (std::size_t k = 0; k < 11 + 2 * calib::core::ParamSet::kSize; ++k) line.empty();
    }
    crosscheck_and_capture_fields(row, line);
    diagnosis_fields(row.run, line);
    out << line.take();
    check_stream(out, "export csv");
    ++rows;
  });
  out.flush();
  check_stream(out, "export csv");
  return rows;
}

std::size_t export_json(const Repository& repo, const ExportFilter& filter, std::ostream& out) {
  out << '[';
  std::size_t rows = 0;
  std::string text;
  repo.export_rows(filter, [&](const ExportRow& row) {
    text.assign(rows == 0 ? "\n" : ",\n");
    append_export_row_json(text, row);
    out << text;
    check_stream(out, "export json");
    ++rows;
  });
  out << (rows == 0 ? "]\n" : "\n]\n");
  out.flush();
  check_stream(out, "export json");
  return rows;
}

std::size_t export_ndjson(const Repository& repo, const ExportFilter& filter, std::ostream& out) {
  std::size_t rows = 0;
  std::string text;
  repo.export_rows(filter, [&](const ExportRow& row) {
    text.clear();
    append_export_row_json(text, row);
    text += '\n';
    out << text;
    check_stream(out, "export ndjson");
    ++rows;
  });
  out.flush();
  check_stream(out, "export ndjson");
  return rows;
}

std::size_t export_history(const Repository& repo, const ExportFilter& filter,
                           const std::string& format, std::ostream& out) {
  if (format == "csv") return export_csv(repo, filter, out);
  if (format == "json") return export_json(repo, filter, out);
  if (format == "ndjson") return export_ndjson(repo, filter, out);
  throw InvalidInput("export format \"" + format + "\" (expected csv, json or ndjson)");
}

namespace {

/// A stored JSON-object column: null when empty, Corrupt when damaged.
json stored_object(const std::string& text, RunId run_id, const char* column) {
  if (text.empty()) return nullptr;
  json parsed = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!parsed.is_object())
    throw Corrupt("run " + std::to_string(run_id) + ": stored " + column + " is not a JSON object");
  return parsed;
}

}  // namespace

json reasons_json(const std::vector<RunReason>& reasons) {
  json a = json::array();
  for (const RunReason& x : reasons) a.push_back({{"source", x.source}, {"text", x.text}});
  return a;
}

json run_json(const RunRecord& r) {
  json o;
  o["run_id"] = r.run_id;
  o["serial"] = r.serial;
  o["state"] = to_string(r.state);
  o["verdict"] = r.verdict ? json(to_string(*r.verdict)) : json(nullptr);
  o["crosscheck_verdict"] =
      r.crosscheck_verdict ? json(to_string(*r.crosscheck_verdict)) : json(nullptr);
  o["started_at"] = format_time_utc(r.started_at_ms);
  o["ended_at"] = r.ended_at_ms ? json(format_time_utc(*r.ended_at_ms)) : json(nullptr);
  o["started_at_ms"] = r.started_at_ms;
  o["ended_at_ms"] = r.ended_at_ms ? json(*r.ended_at_ms) : json(nullptr);
  o["operator"] = r.operator_name;
  o["station"] = r.station;
  o["sequence_name"] = r.sequence_name;
  o["sequence_sha256"] = r.sequence_sha256;
  o["software_version"] = r.software_version;
  o["archive_path"] = r.archive_path;
  o["archive_sha256"] = r.archive_sha256;
  o["failure_reason"] = r.failure_reason;
  o["reasons"] = reasons_json(r.reasons);
  o["reprocessed_from"] = r.reprocessed_from ? json(*r.reprocessed_from) : json(nullptr);
  o["setting"] = calib::core::setting_name(r.setting);
  o["origin"] = r.origin;
  o["promoted_at"] = r.promoted_at_ms ? json(format_time_utc(*r.promoted_at_ms)) : json(nullptr);
  o["promoted_by"] = r.promoted_by;
  o["promote_reason"] = r.promote_reason;
  o["slot"] = r.slot;
  o["table_run"] = r.table_run_id ? json(*r.table_run_id) : json(nullptr);
  o["outcome_of"] = r.verdict ? json(outcome_of(r)) : json(nullptr);
  o["holding_method"] = to_string(r.holding_method);
  o["holding_reason"] = r.holding_reason;
  // Stored only after finish_run validated them as objects; a damaged text is reported, not hidden.
  o["capture"] = stored_object(r.capture_json, r.run_id, "capture_json");
  o["diagnosis"] = stored_object(r.diagnosis_json, r.run_id, "diagnosis_json");
  return o;
}

json calibration_json(const CalibrationRecord& c) {
  json o;
  o["method"] = to_string(c.method);
  o["converged"] = c.converged;
  o["iterations"] = c.iterations;
  o["runtime_s"] = c.runtime_s;
  o["warnings"] = c.warnings;
  o["body_frame"] = to_string(c.body_frame);
  o["unobservable"] = c.unobservable;
  o["notes"] = c.notes;
  o["params"] = params_with_sigma(c);
  if (c.metrics) {
    const StoredMetrics& m = *c.metrics;
    o["metrics"] = {{"orientation_rmse_mdeg", m.orientation_rmse_mdeg},
                    {"accel_rmse_ug", m.accel_rmse_ug},
                    {"heading_offset_gamma_np_rad", m.heading_offset_gamma_np_rad},
                    {"body_misalignment_theta_bp_rad",
                     {m.body_misalignment_theta_bp_rad.x(), m.body_misalignment_theta_bp_rad.y(),
                      m.body_misalignment_theta_bp_rad.z()}}};
  } else {
    o["metrics"] = nullptr;
  }
  return o;
}

json crosscheck_json(const CrosscheckRecord& x) {
  json failures = json::array();
  for (const auto& f : x.failures) failures.push_back({{"term", f.term}, {"detail", f.detail}});
  return {{"verdict", to_string(x.verdict)},
          {"k_sigma", x.k_sigma},
          {"failures", failures},
          {"not_compared", x.not_compared}};
}

json run_details_json(const RunDetails& d) {
  json cals = json::array();
  for (const auto& c : d.calibrations) cals.push_back(calibration_json(c));
  json o;
  o["run"] = run_json(d.run);
  o["calibrations"] = cals;
  o["crosscheck"] = d.crosscheck ? crosscheck_json(*d.crosscheck) : json(nullptr);
  return o;
}

json active_params_json(const ActiveCalibration& a) {
  json j = params_with_sigma(a.active);
  const RunRecord& r = a.run;
  json source = {{"run_id", r.run_id},
                 {"serial", r.serial},
                 {"method", to_string(a.active.method)},
                 {"setting", calib::core::setting_name(r.setting)},
                 {"station", r.station},
                 {"started_at", format_time_utc(r.started_at_ms)},
                 {"verdict", r.verdict ? json(to_string(*r.verdict)) : json(nullptr)},
                 {"body_frame", to_string(a.active.body_frame)},
                 {"not_observable", a.active.unobservable}};
  if (!r.origin.empty()) source["origin"] = r.origin;
  if (!r.holding_reason.empty()) source["holding_reason"] = r.holding_reason;
  if (r.promoted_at_ms) {
    source["promoted_at"] = format_time_utc(*r.promoted_at_ms);
    source["promoted_by"] = r.promoted_by;
    source["promote_reason"] = r.promote_reason;
  }
  j["source"] = std::move(source);
  return j;
}

}  // namespace imucal::db::history
