#include "dtis/io/figures.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <optional>
#include <thread>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"
#include "dtis/io/atomic_file.hpp"

extern char** environ;

namespace dtis::io {
namespace {

namespace fs = std::filesystem;

// The browser to run: options.browser, $DTIS_CHROMIUM, or the first Chromium found on PATH.
std::string FindBrowser(const FigureOptions& options) {
  if (!options.browser.empty()) return options.browser;
  if (const char* env = std::getenv("DTIS_CHROMIUM"); env && *env) return env;
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  for (const char* name : {"chromium", "chromium-browser", "google-chrome"}) {
    for (std::size_t start = 0; start <= dirs.size();) {
      std::size_t colon = dirs.find(':', start);
      if (colon == std::string::npos) colon = dirs.size();
      const fs::path candidate = fs::path(dirs.substr(start, colon - start)) / name;
      if (access(candidate.c_str(), X_OK) == 0) return candidate.string();
      start = colon + 1;
    }
  }
  throw Error(
      "no Chromium to draw the figures with: apt install chromium (scripts/bootstrap does), or set "
      "DTIS_CHROMIUM to a Chromium or Chrome executable");
}

// A temporary folder, removed with everything in it when this goes out of scope.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "dtis-figures-XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw Error("cannot create a temporary folder in {}", pattern);
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& Path() const { return path_; }

 private:
  fs::path path_;
};

// Runs `argv` with stdout and stderr to files; kills it after `timeout_s`, calling `waiting` with
// the time taken about twice a second. Returns its exit status (-1: killed for the timeout).
int RunProcess(const std::vector<std::string>& argv, const fs::path& out, const fs::path& err,
               double timeout_s, const std::function<void(double)>& waiting) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0600);
  // Its own process group, so a timeout kills the browser's helper processes too.
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attr, 0);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, args[0], &actions, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  if (rc != 0) throw Error("cannot run {}: {}", argv[0], std::strerror(rc));
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = start + std::chrono::duration<double>(timeout_s);
  for (int polls = 0;; ++polls) {
    if (waiting && polls % 10 == 0) {
      waiting(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    int status = 0;
    const pid_t done = waitpid(pid, &status, WNOHANG);
    if (done == pid) {
      kill(-pid, SIGKILL);  // helpers left behind
      return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    if (std::chrono::steady_clock::now() > deadline) {
      kill(-pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

// The value of attribute `name` in a start tag, if it has one.
std::optional<std::string> Attribute(std::string_view tag, std::string_view name) {
  std::string key(" ");  // built by appending: GCC 12 warns (-Wrestrict) on " " + name + ...
  key.append(name).append("=\"");
  const std::size_t at = tag.find(key);
  if (at == std::string_view::npos) return std::nullopt;
  const std::size_t begin = at + key.size(), end = tag.find('"', begin);
  if (end == std::string_view::npos) return std::nullopt;
  return std::string(tag.substr(begin, end - begin));
}

// The last lines of a browser's log, for a message.
std::string Tail(const fs::path& log, std::size_t lines) {
  const std::string text = ReadFileText(log.string()).value_or("");
  std::size_t at = text.size();
  for (std::size_t n = 0; n <= lines && at > 0; ++n) at = text.rfind('\n', at - 1);
  return text.substr(at == std::string::npos ? 0 : at + 1);
}

// CRC-32 (ISO 3309, as PNG chunks use it) of `bytes`.
std::uint32_t Crc32(std::string_view bytes) {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char b : bytes) {
    crc ^= b;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return crc ^ 0xFFFFFFFFu;
}

void PutBigEndian(std::uint32_t v, std::string* out) {
  for (int shift = 24; shift >= 0; shift -= 8)
    out->push_back(static_cast<char>((v >> shift) & 0xFFu));
}

std::uint32_t GetBigEndian(std::string_view bytes, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t k = 0; k < 4; ++k) v = (v << 8) | static_cast<unsigned char>(bytes[at + k]);
  return v;
}

}  // namespace

std::string PngWithDpi(std::string_view png, int dpi) {
  constexpr std::string_view kSignature("\x89PNG\r\n\x1a\n", 8);
  if (png.substr(0, 8) != kSignature) throw Error("not a PNG (no PNG signature)");
  std::string out(kSignature);
  bool added = false;
  for (std::size_t at = 8; at < png.size();) {
    if (at + 12 > png.size()) throw Error("not a PNG (a chunk is cut short at byte {})", at);
    const std::uint32_t length = GetBigEndian(png, at);
    if (length > png.size() - at - 12)
      throw Error("not a PNG (a chunk is cut short at byte {})", at);
    const std::string_view type = png.substr(at + 4, 4), chunk = png.substr(at, length + 12);
    if (!added && (type == "IDAT" || type == "IEND")) {
      std::string phys("pHYs");
      const auto per_metre = static_cast<std::uint32_t>(std::lround(dpi / 0.0254));
      PutBigEndian(per_metre, &phys);
      PutBigEndian(per_metre, &phys);
      phys.push_back('\x01');  // the unit is the metre
      PutBigEndian(9, &out);
      out += phys;
      PutBigEndian(Crc32(phys), &out);
      added = true;
    }
    if (type != "pHYs") out.append(chunk);
    at += length + 12;
  }
  if (!added) throw Error("not a PNG (no image data)");
  return out;
}

std::string SvgInMm(std::string_view svg, double width_mm, double height_mm) {
  const std::size_t open = svg.find("<svg");
  const std::size_t close = open == std::string_view::npos ? open : svg.find('>', open);
  if (close == std::string_view::npos) throw Error("not an SVG (no <svg> element)");
  std::string tag(svg.substr(open, close - open));
  const auto width = Attribute(tag, "width"), height = Attribute(tag, "height");
  if (!width || !height) throw Error("the <svg> element has no width and height");
  const auto set = [&tag](std::string_view name, const std::string& from, const std::string& to) {
    const std::string key = fmt::format(" {}=\"{}\"", name, from);
    tag.replace(tag.find(key), key.size(), fmt::format(" {}=\"{}\"", name, to));
  };
  set("width", *width, fmt::format("{:.2f}mm", width_mm));
  set("height", *height, fmt::format("{:.2f}mm", height_mm));
  if (!Attribute(tag, "viewBox")) tag += fmt::format(" viewBox=\"0 0 {} {}\"", *width, *height);
  return std::string(svg.substr(0, open)) + tag + std::string(svg.substr(close));
}

std::string DecodeBase64(std::string_view text) {
  std::string out;
  out.reserve(text.size() / 4 * 3);
  unsigned bits = 0;
  int count = 0;
  std::size_t padding = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    int v = -1;
    if (c >= 'A' && c <= 'Z')
      v = c - 'A';
    else if (c >= 'a' && c <= 'z')
      v = c - 'a' + 26;
    else if (c >= '0' && c <= '9')
      v = c - '0' + 52;
    else if (c == '+')
      v = 62;
    else if (c == '/')
      v = 63;
    else if (c == '=') {
      ++padding;
      continue;
    } else if (c == ' ' || c == '\n' || c == '\r' || c == '\t') {
      continue;
    }
    if (v < 0 || padding > 0) {
      throw Error("base64: unexpected character '{}' at offset {}", c, i);
    }
    bits = (bits << 6) | static_cast<unsigned>(v);
    count += 6;
    if (count >= 8) {
      count -= 8;
      out.push_back(static_cast<char>((bits >> count) & 0xFFu));
    }
  }
  // What is left must be the zero bits of a partial group: 2 or 4 of them, never a lone 6.
  if (count >= 6 || padding > 2 || (bits & ((1u << count) - 1u)) != 0) {
    throw Error("base64: truncated or malformed ending");
  }
  return out;
}

std::vector<Figure> ParseFigures(std::string_view dom, const std::string& source) {
  std::vector<Figure> figures;
  constexpr std::string_view kOpen = "<pre class=\"figure\"";
  for (std::size_t at = dom.find(kOpen); at != std::string_view::npos; at = dom.find(kOpen, at)) {
    const std::size_t tag_end = dom.find('>', at);
    const std::size_t close = dom.find("</pre>", at);
    if (tag_end == std::string_view::npos || close == std::string_view::npos || close < tag_end) {
      throw Error("{}: a figure element is not closed", source);
    }
    const std::string_view tag = dom.substr(at, tag_end - at);
    Figure f;
    const auto name = Attribute(tag, "data-name"), format = Attribute(tag, "data-format");
    if (!name || !format || name->empty() || format->empty()) {
      throw Error("{}: a figure has no data-name or data-format", source);
    }
    // Names become file names: letters, digits, '-' and '_' only.
    for (char c : *name + *format) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') {
        throw Error("{}: figure name '{}.{}' is not a plain file name", source, *name, *format);
      }
    }
    f.name = *name;
    f.format = *format;
    for (auto [key, value] :
         {std::pair{"data-width-mm", &f.width_mm}, {"data-height-mm", &f.height_mm}}) {
      const auto text = Attribute(tag, key);
      if (!text) continue;
      char* end = nullptr;
      *value = std::strtod(text->c_str(), &end);
      if (end == text->c_str() || *end != '\0' || !(*value > 0.0 && *value < 1e4)) {
        throw Error("{}: figure {}.{}: {}=\"{}\" is not a size in mm", source, f.name, f.format,
                    key, *text);
      }
    }
    try {
      f.bytes = DecodeBase64(dom.substr(tag_end + 1, close - tag_end - 1));
    } catch (const Error& e) {
      throw Error("{}: figure {}.{}: {}", source, f.name, f.format, e.what());
    }
    figures.push_back(std::move(f));
    at = close;
  }
  return figures;
}

std::vector<std::string> ExportFigures(const std::string& report_html, const std::string& out_dir,
                                       const FigureOptions& options) {
  if (!fs::is_regular_file(report_html)) {
    throw Error("{}: no such report; write one with dtis run --report (or report, compare, stream)",
                report_html);
  }
  std::string formats;
  for (const auto& f : options.formats) {
    if (f != "png" && f != "svg" && f != "jpeg" && f != "webp") {
      throw Error("figure format '{}': expected png, svg, jpeg or webp", f);
    }
    formats += (formats.empty() ? "" : ",") + f;
  }
  if (formats.empty()) throw Error("no figure format asked for: expected png, svg, jpeg or webp");
  const std::string browser = FindBrowser(options);
  const TempDir temp;
  const fs::path dom = temp.Path() / "dom.html", log = temp.Path() / "browser.log";
  const std::string url = "file://" + fs::absolute(report_html).lexically_normal().string() +
                          "#figures=" + formats +
                          fmt::format("&width_mm={:g}&dpi={}", options.width_mm, options.dpi) +
                          (options.pass > 0 ? fmt::format("&pass={}", options.pass) : "");
  const std::vector<std::string> argv = {browser,
                                         "--headless",
                                         "--no-sandbox",
                                         "--disable-gpu",
                                         "--use-gl=swiftshader",
                                         "--enable-unsafe-swiftshader",
                                         "--virtual-time-budget=120000",
                                         "--hide-scrollbars",
                                         "--user-data-dir=" + (temp.Path() / "profile").string(),
                                         "--dump-dom",
                                         url};
  const int status = RunProcess(argv, dom, log, options.timeout_s, options.waiting);
  if (status == -1) {
    throw Error("{}: the browser ({}) did not finish drawing the figures in {:g} s", report_html,
                browser, options.timeout_s);
  }
  const std::string text = ReadFileText(dom.string()).value_or("");
  const std::size_t body = text.find("<body");
  const std::string_view body_tag =
      body == std::string::npos ? std::string_view()
                                : std::string_view(text).substr(body, text.find('>', body) - body);
  if (status != 0 || Attribute(body_tag, "data-figures") != "done") {
    const std::string page = Attribute(body_tag, "data-report-status").value_or("not loaded");
    throw Error("{}: the browser ({}) drew no figures (exit status {}, page status '{}'): {}",
                report_html, browser, status, page, Tail(log, 5));
  }
  // The figures are the last element of the page: after the scripts, whatever they hold.
  const std::size_t holder = text.rfind("<div id=\"figures\"");
  const std::vector<Figure> figures = ParseFigures(
      std::string_view(text).substr(holder == std::string::npos ? 0 : holder), report_html);
  if (figures.empty()) throw Error("{}: the page holds no plots to draw", report_html);
  fs::create_directories(out_dir);
  std::deque<AtomicFile> files;
  std::vector<std::string> written;
  for (const auto& f : figures) {
    written.push_back((fs::path(out_dir) / (f.name + "." + f.format)).string());
    std::string bytes = f.bytes;
    try {
      if (f.format == "png") bytes = PngWithDpi(bytes, options.dpi);
      if (f.format == "svg" && f.width_mm > 0 && f.height_mm > 0) {
        bytes = SvgInMm(bytes, f.width_mm, f.height_mm);
      }
    } catch (const Error& e) {
      throw Error("{}: figure {}.{}: {}", report_html, f.name, f.format, e.what());
    }
    files.emplace_back(written.back()).Write(bytes);
  }
  std::vector<AtomicFile*> all;
  for (auto& f : files) all.push_back(&f);
  CommitTogether(all);
  return written;
}

}  // namespace dtis::io
