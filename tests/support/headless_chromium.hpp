#pragma once
// A page as a browser shows it, for the web tests: headless Chromium (tools/setup.sh installs it)
// dumps the DOM after scripts ran, reports the console's messages, and takes screenshots.
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "tests/support/run_command.hpp"

namespace imucal::test_support {

inline const char* const kHeadlessChromium =
    "timeout 120 chromium --headless --no-sandbox --disable-gpu --hide-scrollbars "
    "--enable-logging=stderr --v=0 ";

inline bool chromium_installed() { return run_command("command -v chromium >/dev/null").code == 0; }

struct RenderedPage {
  int code = -1;                     ///< chromium's exit status
  std::string dom;                   ///< the DOM after load
  std::vector<std::string> console;  ///< the log lines of console messages (none for a clean page)
};

/// `url` loaded; chromium's log goes to `log_path` (read back for console messages).
inline RenderedPage render_in_chromium(const std::string& url, const std::string& log_path) {
  RenderedPage page;
  const CommandResult r =
      run_command(std::string(kHeadlessChromium) + "--dump-dom '" + url + "' 2>" + log_path);
  page.code = r.code;
  page.dom = r.out;
  std::ifstream log(log_path);
  for (std::string line; std::getline(log, line);)
    if (line.find(":CONSOLE") != std::string::npos) page.console.push_back(line);
  return page;
}

/// `dom` with its attributes in single quotes, as stationweb writes them, so that the tests' tag
/// reader (html_tags.hpp) reads a page as Chromium shows it: Chromium serialises attributes in
/// double quotes and writes a single quote inside one as it is.
inline std::string single_quoted(const std::string& dom) {
  static const std::regex dq("([a-z0-9-]+)=\"([^\"]*)\"");
  std::string out;
  auto last = dom.cbegin();
  for (std::sregex_iterator it(dom.begin(), dom.end(), dq), end; it != end; ++it) {
    out.append(last, (*it)[0].first);
    std::string value = (*it)[2];
    for (std::size_t q = value.find('\''); q != std::string::npos; q = value.find('\'', q))
      value.replace(q, 1, "&#39;");
    out += (*it)[1].str() + "='" + value + "'";
    last = (*it)[0].second;
  }
  out.append(last, dom.cend());
  return out;
}

/// A screenshot of `url`, `width` × `height` px, to `png_path`; chromium's exit status.
inline int chromium_screenshot(const std::string& url, const std::string& png_path, int width,
                               int height) {
  return run_command(std::string(kHeadlessChromium) + "--window-size=" + std::to_string(width) +
                     "," + std::to_string(height) + " --screenshot=" + png_path + " '" + url +
                     "' 2>/dev/null")
      .code;
}

}  // namespace imucal::test_support
