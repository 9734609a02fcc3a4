// tools/render/text_overlay.hpp — lines of text as triangles, for `weft view`'s readouts:
// a 5 x 7 pixel font drawn cell by cell (each lit cell a square of `scale` pixels), so the
// renderer draws text with the same shader as everything else and needs no texture.
#pragma once

#include <string>
#include <vector>

namespace weftrender {

/// Appends the triangles (x, y pairs in pixels from the bottom left of the viewport) of
/// `text` with its top left corner at (left, top). Characters the font lacks are drawn
/// as '?'; upper case is drawn as lower case. Each character advances 6 x scale pixels.
void appendText(const std::string& text, float left, float top, float scale, std::vector<float>& triangles);

/// A rectangle as two triangles (pixels).
void appendRectangle(float left, float bottom, float right, float top, std::vector<float>& triangles);

}  // namespace weftrender
