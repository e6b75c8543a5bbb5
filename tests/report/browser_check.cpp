#include "report/browser_check.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>

namespace hil::test {
namespace fs = std::filesystem;
namespace {

std::string read_all(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string file_url(const fs::path& file) {
  const std::string p = fs::absolute(file).lexically_normal().string();
  std::string url = "file://";
  const char* hex = "0123456789ABCDEF";
  for (unsigned char c : p) {
    if (std::isalnum(c) || c == '/' || c == '-' || c == '_' || c == '.' || c == '~') {
      url += static_cast<char>(c);
    } else {
      url += '%';
      url += hex[c >> 4];
      url += hex[c & 15];
    }
  }
  return url;
}

// Runs chromium with the flags this machine needs (no sandbox as root, no background network
// traffic, which a closed network refuses) and a fresh profile; stdout goes to `out`.
std::string run_chromium(std::vector<std::string> extra, const fs::path& out, std::chrono::seconds timeout) {
  const fs::path chromium = find_chromium();
  if (chromium.empty()) {
    return "Chromium not found (looked at $HIL_CHROMIUM, /usr/bin/chromium, chromium-browser, "
           "google-chrome): install it with `scripts/setup.sh --test` (Debian package chromium)";
  }
  std::string tmpl = (fs::temp_directory_path() / "hil-chromium-XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) return "cannot create a Chromium profile folder";
  const fs::path profile = tmpl;
  const fs::path err_file = profile / "stderr.txt";
  std::vector<std::string> args = {chromium.string(),
                                   "--headless",
                                   "--no-sandbox",
                                   "--disable-gpu",
                                   "--disable-quic",
                                   "--no-first-run",
                                   "--disable-background-networking",
                                   "--disable-component-update",
                                   "--disable-sync",
                                   "--disable-extensions",
                                   "--disable-dev-shm-usage",
                                   "--no-default-browser-check",
                                   "--mute-audio",
                                   "--hide-scrollbars",
                                   "--force-device-scale-factor=1",
                                   "--user-data-dir=" + profile.string()};
  args.insert(args.end(), extra.begin(), extra.end());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  const pid_t pid = ::fork();
  if (pid < 0) return "fork failed";
  if (pid == 0) {
    ::setpgid(0, 0);  // own process group: a timeout kills Chromium's children too
    const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int e = ::open(err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int in = ::open("/dev/null", O_RDONLY);
    if (o < 0 || e < 0 || in < 0) ::_exit(126);
    ::dup2(in, 0), ::dup2(o, 1), ::dup2(e, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::setpgid(pid, pid);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  int status = 0;
  std::string error;
  for (;;) {
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) break;
    if (r < 0) {
      error = "waitpid failed";
      break;
    }
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(-pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      error = "Chromium did not finish within " + std::to_string(timeout.count()) + " s";
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ::kill(-pid, SIGKILL);  // leftover renderer or zygote processes of this run only
  if (error.empty() && !(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
    std::string tail = read_all(err_file);
    if (tail.size() > 1500) tail = tail.substr(tail.size() - 1500);
    error = "Chromium failed (" +
            (WIFEXITED(status) ? "exit " + std::to_string(WEXITSTATUS(status)) : "signal " + std::to_string(WTERMSIG(status))) +
            "): " + tail;
  }
  std::error_code ec;
  fs::remove_all(profile, ec);
  return error;
}

std::string attr(const std::string& tag, const std::string& name) {
  const std::string key = " " + name + "=\"";
  const auto p = tag.find(key);
  if (p == std::string::npos) return {};
  const auto b = p + key.size();
  const auto e = tag.find('"', b);
  return e == std::string::npos ? std::string() : tag.substr(b, e - b);
}

long to_long(const std::string& s, long fallback) {
  char* end = nullptr;
  const long v = std::strtol(s.c_str(), &end, 10);
  return (s.empty() || *end != '\0') ? fallback : v;
}

}  // namespace

fs::path find_chromium() {
  if (const char* env = std::getenv("HIL_CHROMIUM"); env != nullptr && *env != '\0') {
    return ::access(env, X_OK) == 0 ? fs::path(env) : fs::path();
  }
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"}) {
    if (::access(p, X_OK) == 0) return p;
  }
  return {};
}

bool BrowserResult::ok() const {
  if (!error.empty() || plots < 0 || plot_errors != 0 || canvases.empty()) return false;
  for (const auto& c : canvases) {
    if (!c.rendered || (!c.empty && c.ink <= 0)) return false;
  }
  return true;
}

std::string BrowserResult::summary() const {
  std::ostringstream s;
  if (!error.empty()) s << "error: " << error << "; ";
  int rendered = 0, empty = 0;
  for (const auto& c : canvases) rendered += c.rendered, empty += c.empty;
  s << "plots=" << plots << " plot_errors=" << plot_errors << " canvases=" << canvases.size() << " rendered=" << rendered
    << " empty=" << empty << " min_ink=" << min_ink;
  if (!first_error.empty()) s << " first_error=\"" << first_error << '"';
  return s.str();
}

std::string BrowserResult::body_attribute(const std::string& name) const {
  const auto at = dom.find("<body");
  if (at == std::string::npos) return {};
  return attr(dom.substr(at, dom.find('>', at) - at), name);
}

BrowserResult check_report_in_chromium(const fs::path& html, std::chrono::seconds timeout) {
  BrowserResult r;
  if (!fs::exists(html)) {
    r.error = "no such report: " + html.string();
    return r;
  }
  const fs::path out = fs::temp_directory_path() / ("hil-dom-" + std::to_string(::getpid()) + ".html");
  // #ink: the page counts the pixels each plot drew (report.js does only when asked).
  r.error = run_chromium({"--window-size=1400,2000", "--virtual-time-budget=10000", "--dump-dom", file_url(html) + "#ink"}, out,
                         timeout);
  r.dom = read_all(out);
  std::error_code ec;
  fs::remove(out, ec);
  if (!r.error.empty()) return r;

  const auto body_at = r.dom.find("<body");
  if (body_at == std::string::npos) {
    r.error = "Chromium printed no <body> (" + std::to_string(r.dom.size()) + " bytes of DOM)";
    return r;
  }
  const std::string body = r.dom.substr(body_at, r.dom.find('>', body_at) - body_at);
  r.plots = static_cast<int>(to_long(attr(body, "data-plots"), -1));
  r.plot_errors = static_cast<int>(to_long(attr(body, "data-plot-errors"), -1));
  r.first_error = attr(body, "data-plot-error-first");
  if (r.plots < 0) r.error = "the page's script did not publish data-plots on <body> (did it run?)";

  // Report data is embedded with '<' escaped, so "<canvas" only starts real elements.
  for (auto p = r.dom.find("<canvas"); p != std::string::npos; p = r.dom.find("<canvas", p + 1)) {
    const std::string tag = r.dom.substr(p, r.dom.find('>', p) - p);
    if (attr(tag, "class").find("hil-plot") == std::string::npos) continue;
    CanvasInfo c;
    c.rendered = attr(tag, "data-rendered") == "1";
    c.empty = attr(tag, "data-empty") == "1";
    c.ink = to_long(attr(tag, "data-ink"), -1);
    if (!c.empty && (r.min_ink < 0 || c.ink < r.min_ink)) r.min_ink = c.ink;
    r.canvases.push_back(c);
  }
  return r;
}

std::string screenshot_in_chromium(const fs::path& html, const fs::path& png, int width, int height,
                                   std::chrono::seconds timeout) {
  if (!fs::exists(html)) return "no such report: " + html.string();
  std::error_code ec;
  fs::remove(png, ec);
  const fs::path out = fs::temp_directory_path() / ("hil-shot-" + std::to_string(::getpid()) + ".txt");
  std::string error = run_chromium({"--window-size=" + std::to_string(width) + "," + std::to_string(height),
                                    "--virtual-time-budget=10000", "--screenshot=" + fs::absolute(png).string(), file_url(html)},
                                   out, timeout);
  fs::remove(out, ec);
  if (error.empty() && !fs::exists(png)) error = "Chromium wrote no screenshot to " + png.string();
  return error;
}

}  // namespace hil::test
