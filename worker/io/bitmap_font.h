// SPDX-License-Identifier: Apache-2.0
// A 5 x 7 pixel bitmap font for the labels of previews ("100 m", "step 2500",
// "3.2 yr", "sand m", "N"): erg links no font library, and these few glyphs
// are all a preview writes. Each glyph is seven rows, top first, of five bits
// (bit 4 the leftmost pixel); a character without a glyph draws as a box,
// so a label that needs a new glyph shows at once.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

namespace erg::io::font {

inline constexpr int kGlyphW = 5, kGlyphH = 7;
inline constexpr int kAdvance = kGlyphW + 1;  // one blank column between characters

using Glyph = std::array<std::uint8_t, kGlyphH>;

// The rows of `c`'s glyph; a hollow box for a character the font lacks.
constexpr Glyph glyph(char c) {
  switch (c) {
    case ' ':
      return {0, 0, 0, 0, 0, 0, 0};
    case '.':
      return {0, 0, 0, 0, 0, 0b01100, 0b01100};
    case '-':
      return {0, 0, 0, 0b11111, 0, 0, 0};
    case '0':
      return {0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110};
    case '1':
      return {0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110};
    case '2':
      return {0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111};
    case '3':
      return {0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110};
    case '4':
      return {0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010};
    case '5':
      return {0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110};
    case '6':
      return {0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110};
    case '7':
      return {0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000};
    case '8':
      return {0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110};
    case '9':
      return {0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100};
    case 'a':
      return {0, 0, 0b01110, 0b00001, 0b01111, 0b10001, 0b01111};
    case 'd':
      return {0b00001, 0b00001, 0b01101, 0b10011, 0b10001, 0b10001, 0b01111};
    case 'e':
      return {0, 0, 0b01110, 0b10001, 0b11111, 0b10000, 0b01110};
    case 'i':
      return {0b00100, 0, 0b01100, 0b00100, 0b00100, 0b00100, 0b01110};
    case 'k':
      return {0b10000, 0b10000, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010};
    case 'm':
      return {0, 0, 0b11010, 0b10101, 0b10101, 0b10001, 0b10001};
    case 'n':
      return {0, 0, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001};
    case 'p':
      return {0, 0, 0b11110, 0b10001, 0b11110, 0b10000, 0b10000};
    case 'r':
      return {0, 0, 0b10110, 0b11001, 0b10000, 0b10000, 0b10000};
    case 's':
      return {0, 0, 0b01110, 0b10000, 0b01110, 0b00001, 0b11110};
    case 't':
      return {0b01000, 0b01000, 0b11100, 0b01000, 0b01000, 0b01001, 0b00110};
    case 'w':
      return {0, 0, 0b10001, 0b10001, 0b10101, 0b10101, 0b01010};
    case 'y':
      return {0, 0, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110};
    case 'N':
      return {0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001, 0b10001};
    default:
      return {0b11111, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b11111};
  }
}

// Width in pixels of `text` drawn at `scale` (no trailing blank column).
constexpr int text_width(std::string_view text, int scale) {
  return text.empty() ? 0 : (static_cast<int>(text.size()) * kAdvance - 1) * scale;
}

// Calls plot(x, y) for every lit pixel of `text` with its top-left corner at
// (x0, y0), each font pixel a scale x scale block.
template <class Plot>
void draw_text(std::string_view text, int x0, int y0, int scale, Plot&& plot) {
  for (std::size_t k = 0; k < text.size(); ++k) {
    const Glyph g = glyph(text[k]);
    const int gx = x0 + static_cast<int>(k) * kAdvance * scale;
    for (int row = 0; row < kGlyphH; ++row)
      for (int col = 0; col < kGlyphW; ++col)
        if (g[static_cast<std::size_t>(row)] & (1u << (kGlyphW - 1 - col)))
          for (int dy = 0; dy < scale; ++dy)
            for (int dx = 0; dx < scale; ++dx) plot(gx + col * scale + dx, y0 + row * scale + dy);
  }
}

}  // namespace erg::io::font
