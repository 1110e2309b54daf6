#pragma once
// Reading stationweb's pages in tests: the attributes of tags (the pages carry their numbers in
// data attributes), a page's section by element id, a number as text. Shared by
// tests/tools/stationweb_test.cpp and tests/fleet/stationweb_fleet_test.cpp.
#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <regex>
#include <string>
#include <vector>

namespace imucal::test_support {

/// An element's attributes; reading one it does not have is a test failure (not a silent "").
struct Attrs : std::map<std::string, std::string> {
  const std::string& operator[](const std::string& key) const {
    static const std::string none;
    const auto it = find(key);
    if (it != end()) return it->second;
    ADD_FAILURE() << "the element has no attribute " << key;
    return none;
  }
};

inline std::string unescape(std::string s) {
  const std::pair<const char*, const char*> entities[] = {
      {"&#39;", "'"}, {"&quot;", "\""}, {"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}};
  for (const auto& [from, to] : entities)
    for (std::size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + 1))
      s.replace(p, std::string(from).size(), to);
  return s;
}

/// The attributes of every tag that starts with `open` (e.g. "<tr class='run'"), in page order.
inline std::vector<Attrs> tags(const std::string& html, const std::string& open) {
  std::vector<Attrs> out;
  static const std::regex attr("([a-z0-9-]+)='([^']*)'");
  for (std::size_t p = html.find(open); p != std::string::npos; p = html.find(open, p + 1)) {
    const std::string tag = html.substr(p, html.find('>', p) - p);
    Attrs a;
    for (std::sregex_iterator it(tag.begin(), tag.end(), attr), end; it != end; ++it)
      a.insert_or_assign((*it)[1], unescape((*it)[2]));
    out.push_back(a);
  }
  return out;
}

/// The part of the page from the element with id `id` to the next `end` (e.g. "</table>").
inline std::string section(const std::string& html, const std::string& id, const std::string& end) {
  const std::size_t p = html.find("id='" + id + "'");
  if (p == std::string::npos) return "";
  return html.substr(p, html.find(end, p) - p);
}

inline double number(const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  EXPECT_TRUE(!text.empty() && *end == '\0') << "not a number: \"" << text << "\"";
  return v;
}

}  // namespace imucal::test_support
