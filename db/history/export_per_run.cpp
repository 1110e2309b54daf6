#include "db/history/export_per_run.hpp"

#include <iterator>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <streambuf>
#include <vector>

#include "calib/core/param_set.hpp"
#include "db/history/export.hpp"

namespace imucal::db::history {

namespace {

using nlohmann::json;

constexpr Method kPerRunMethodOrder[] = {Method::kAins, Method::kNlsq, Method::kLegacy};

void check_per_run_stream(std::ostream& out, const char* what) {
  if (!out)
    throw IoError(std::string(what) + ": writing the output failed (disk full or closed pipe?)");
}

/// Takes export_csv's bytes — a header, then a row per run and method, records ending in CRLF,
/// a field quoted when it holds a comma, quote, CR or LF — and writes the per-run shape to `out`.
/// export_rows hands a run's rows one after the other: they are collected while the run_id stays
/// the same and written as one row when it changes. Regrouping the default shape's own fields
/// (rather than writing the columns a second time) keeps the two shapes' columns and numbers one
/// definition.
class PerRunCsv : public std::streambuf {
 public:
  explicit PerRunCsv(std::ostream& out) : out_(out) {}

  /// Writes the last run's row; the number of runs written.
  std::size_t finish() {
    flush_run();
    return runs_;
  }

 protected:
  int_type overflow(int_type c) override {
    if (!traits_type::eq_int_type(c, traits_type::eof())) take(traits_type::to_char_type(c));
    return traits_type::not_eof(c);
  }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    for (std::streamsize i = 0; i < n; ++i) take(s[i]);
    return n;
  }

 private:
  // Where the default shape's blocks lie: the run, one calibration, then the run's tail.
  static constexpr std::size_t kRun = std::size(kCsvRunColumns);
  static constexpr std::size_t kCalibration =
      std::size(kCsvCalibrationColumns) + 2 * calib::core::ParamSet::kSize;

  void take(char c) {
    if (closed_quote_) {
      closed_quote_ = false;
      if (c == '"') {  // a doubled quote inside a quoted field
        field_ += '"';
        quoted_ = true;
        return;
      }
    }
    if (quoted_) {
      if (c == '"') {
        quoted_ = false;
        closed_quote_ = true;
      } else {
        field_ += c;
      }
      return;
    }
    if (c == '"') {
      quoted_ = true;
    } else if (c == ',') {
      fields_.push_back(std::move(field_));
      field_.clear();
    } else if (c == '\n') {
      fields_.push_back(std::move(field_));
      field_.clear();
      record(std::move(fields_));
      fields_.clear();
    } else if (c != '\r') {  // outside quotes a CR only ends a record, before its LF
      field_ += c;
    }
  }

  void record(std::vector<std::string> fields) {
    if (columns_ == 0) return header(fields);
    if (fields.size() != columns_)
      throw std::logic_error("export --per-run: a row of " + std::to_string(fields.size()) +
                             " fields under a header of " + std::to_string(columns_));
    if (!rows_.empty() && rows_.front().front() != fields.front()) flush_run();
    rows_.push_back(std::move(fields));
  }

  void header(const std::vector<std::string>& names) {
    columns_ = names.size();
    if (columns_ < kRun + kCalibration)
      throw std::logic_error("export --per-run: the CSV header has too few columns");
    std::vector<std::string> out(names.begin(), names.begin() + kRun);
    for (const Method m : kPerRunMethodOrder)
      for (std::size_t k = kRun + 1; k < kRun + kCalibration; ++k)  // without "method"
        out.push_back(std::string(to_string(m)) + "." + names[k]);
    out.insert(out.end(), names.begin() + kRun + kCalibration, names.end());
    write(out);
  }

  /// The collected rows of one run as one row.
  void flush_run() {
    if (rows_.empty()) return;
    const std::vector<std::string>& first = rows_.front();
    std::vector<std::string> out(first.begin(), first.begin() + kRun);
    for (const Method m : kPerRunMethodOrder) {
      const std::vector<std::string>* row = nullptr;
      for (const auto& r : rows_)
        if (r[kRun] == to_string(m)) row = &r;
      for (std::size_t k = kRun + 1; k < kRun + kCalibration; ++k)
        out.push_back(row ? (*row)[k] : std::string());
    }
    out.insert(out.end(), first.begin() + kRun + kCalibration, first.end());
    write(out);
    rows_.clear();
    ++runs_;
  }

  void write(const std::vector<std::string>& fields) {
    std::string line;
    for (std::size_t i = 0; i < fields.size(); ++i)
      line += (i == 0 ? "" : ",") + csv_field(fields[i]);
    out_ << line << "\r\n";
    check_per_run_stream(out_, "export csv --per-run");
  }

  std::ostream& out_;
  std::string field_;
  std::vector<std::string> fields_;
  bool quoted_ = false, closed_quote_ = false;
  std::size_t columns_ = 0;
  std::vector<std::vector<std::string>> rows_;
  std::size_t runs_ = 0;
};

std::size_t export_csv_per_run(const Repository& repo, const ExportFilter& filter,
                               std::ostream& out) {
  PerRunCsv regroup(out);
  std::ostream rows(&regroup);
  // An error of the real output (or of the regrouping) surfaces as itself, not as a failed stream.
  rows.exceptions(std::ios::badbit);
  (void)export_csv(repo, filter, rows);
  const std::size_t runs = regroup.finish();
  out.flush();
  check_per_run_stream(out, "export csv --per-run");
  return runs;
}

/// JSON and NDJSON per run: the run's rows gathered into one object each.
std::size_t export_json_per_run(const Repository& repo, const ExportFilter& filter, bool ndjson,
                                std::ostream& out) {
  std::size_t runs = 0;
  json object;
  const auto flush = [&] {
    if (object.is_null()) return;
    if (!ndjson) out << (runs == 0 ? "\n" : ",\n");
    out << object.dump(-1, ' ', false, json::error_handler_t::strict) << (ndjson ? "\n" : "");
    check_per_run_stream(out, "export json --per-run");
    object = json();
    ++runs;
  };
  if (!ndjson) out << '[';
  repo.export_rows(filter, [&](const ExportRow& row) {
    if (!object.is_null() && object["run_id"] != json(row.run.run_id)) flush();
    if (object.is_null()) {
      object = run_json(row.run);
      object["calibrations"] = json::array();
      object["crosscheck"] = row.crosscheck ? crosscheck_json(*row.crosscheck) : json(nullptr);
    }
    if (row.calibration) object["calibrations"].push_back(calibration_json(*row.calibration));
  });
  flush();
  if (!ndjson) out << (runs == 0 ? "]\n" : "\n]\n");
  out.flush();
  check_per_run_stream(out, "export json --per-run");
  return runs;
}

}  // namespace

std::size_t export_per_run(const Repository& repo, const ExportFilter& filter,
                           const std::string& format, std::ostream& out) {
  if (format == "csv") return export_csv_per_run(repo, filter, out);
  if (format == "json") return export_json_per_run(repo, filter, false, out);
  if (format == "ndjson") return export_json_per_run(repo, filter, true, out);
  throw InvalidInput("export format \"" + format + "\" (expected csv, json or ndjson)");
}

std::size_t export_in_shape(const Repository& repo, const ExportFilter& filter,
                            const std::string& format, bool per_run, std::ostream& out) {
  return per_run ? export_per_run(repo, filter, format, out)
                 : export_history(repo, filter, format, out);
}

}  // namespace imucal::db::history
