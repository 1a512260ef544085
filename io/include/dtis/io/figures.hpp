// Static figures of a report: every plot of a dtis HTML report as PNG and SVG, for
// papers. The report itself draws them: a headless Chromium (Debian's `chromium`) opens it with
// #figures=png,svg in the address, plotly.js exports each plot (Plotly.toImage), and the images
// come back in the browser's DOM dump. So a figure is the very plot the report shows, drawn by the
// same library, not a second plotting code path.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace dtis::io {

struct FigureOptions {
  std::vector<std::string> formats{"png", "svg"};  // of png, svg, jpeg, webp
  // Print size: every figure is laid out this wide (a column of a two-column paper: 88 mm; a
  // page: 180 mm), its height set by the plot; text is 7 to 8 pt at that size. PNGs are drawn at
  // `dpi` and say so (pHYs), SVGs carry their size in mm.
  double width_mm = 88.0;
  int dpi = 300;
  int pass = 0;  // > 0: the feed figure shows this pass alone (surface jobs), 1 the first
  // The browser: "" for $DTIS_CHROMIUM, else chromium (or chromium-browser, google-chrome) on PATH.
  std::string browser;
  double timeout_s = 300.0;  // wall clock for the browser
  // Called about twice a second while the browser draws, with the seconds it has taken so far.
  std::function<void(double)> waiting;
};

struct Figure {
  std::string name;                        // path, feed, usage, compare-feed, axis-X, ...
  std::string format;                      // png, svg, ...
  std::string bytes;                       // the file's content
  double width_mm = 0.0, height_mm = 0.0;  // its print size, when the page says (else 0)
};

// Renders the report's figures and writes each as OUT_DIR/NAME.FORMAT, atomically (all of them are
// rendered before the first is written). Returns the files written. Throws dtis::Error naming the
// report and what went wrong (no browser, the page failed, a figure missing).
std::vector<std::string> ExportFigures(const std::string& report_html, const std::string& out_dir,
                                       const FigureOptions& options = {});

// The figures a report's DOM dump carries (<pre class="figure" data-name data-format>BASE64</pre>).
// Throws dtis::Error naming `source` when one is malformed.
std::vector<Figure> ParseFigures(std::string_view dom, const std::string& source);

// A PNG that says it is `dpi` dots per inch (its pHYs chunk, before the image data; any other
// pHYs is dropped). Throws dtis::Error when `png` is not a PNG.
std::string PngWithDpi(std::string_view png, int dpi);

// An SVG whose root element's width and height are in mm (its pixel size becomes its viewBox), so
// it prints at that size. Throws dtis::Error when `svg` has no <svg> element with width and
// height.
std::string SvgInMm(std::string_view svg, double width_mm, double height_mm);

// Standard base64 (RFC 4648, padding optional, whitespace ignored). Throws dtis::Error on any other
// character.
std::string DecodeBase64(std::string_view text);

}  // namespace dtis::io
