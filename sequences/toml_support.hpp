#pragma once
// Small helpers shared by the project's TOML readers (sequences, run.toml, unit files, register
// maps): wording of types in error messages.
#include <toml++/toml.h>

namespace imucal::sequences {

/// The word used in error messages for a TOML node type ("float", "table", ...).
inline const char* toml_type_name(toml::node_type t) {
  switch (t) {
    case toml::node_type::table: return "table";
    case toml::node_type::array: return "array";
    case toml::node_type::string: return "string";
    case toml::node_type::integer: return "integer";
    case toml::node_type::floating_point: return "float";
    case toml::node_type::boolean: return "boolean";
    case toml::node_type::date: return "date";
    case toml::node_type::time: return "time";
    case toml::node_type::date_time: return "date-time";
    default: return "nothing";
  }
}

}  // namespace imucal::sequences
