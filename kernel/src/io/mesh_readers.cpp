#include "mesh_readers.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "../core/text.hpp"

namespace weft::io_detail {

namespace {

[[noreturn]] void refuse(const std::string& what) { throw std::runtime_error(what); }

char lower(char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c; }

bool equalsIgnoringCase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t k = 0; k < a.size(); ++k)
    if (lower(a[k]) != lower(b[k])) return false;
  return true;
}

/// `text` quoted for a message: at most 40 bytes, those that are not printable as \xNN.
std::string quoted(std::string_view text) { return "'" + detail::escaped(text, 40) + "'"; }

std::string counted(std::uint64_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

/// `v` rounded to float, as a PLY `property float` declares it: beyond float's range an
/// infinity (which the mesh cleaning refuses, naming the vertex), not undefined behaviour.
double asDeclaredFloat(double v) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (v > kMax) return std::numeric_limits<double>::infinity();
  if (v < -kMax) return -std::numeric_limits<double>::infinity();
  return static_cast<double>(static_cast<float>(v));
}

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }

/// Parses a whole token as a number (a leading '+' allowed); false if it is not one.
bool parseNumber(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && end == token.data() + token.size();
}

bool parseWhole(std::string_view token, std::int64_t& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && end == token.data() + token.size();
}

/// Splits text into white-space separated tokens, counting lines for messages.
class Tokens {
 public:
  explicit Tokens(std::string_view text, std::int64_t firstLine = 1) : text_(text), line_(firstLine) {}
  /// The next token, or an empty view at the end.
  std::string_view next() {
    while (pos_ < text_.size() && isSpace(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    const size_t start = pos_;
    while (pos_ < text_.size() && !isSpace(text_[pos_])) ++pos_;
    tokenLine_ = line_;
    return text_.substr(start, pos_ - start);
  }
  /// Skips the rest of the current line.
  void skipLine() {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  }
  std::int64_t line() const { return tokenLine_; }

 private:
  std::string_view text_;
  size_t pos_ = 0;
  std::int64_t line_;
  std::int64_t tokenLine_ = 0;
};

// ---------------------------------------------------------------------------------------
// PLY

enum class Type : std::uint8_t { I8, U8, I16, U16, I32, U32, F32, F64 };

bool typeNamed(std::string_view name, Type& type) {
  static constexpr std::pair<std::string_view, Type> kTypes[] = {
      {"char", Type::I8},   {"int8", Type::I8},     {"uchar", Type::U8},   {"uint8", Type::U8},
      {"short", Type::I16}, {"int16", Type::I16},   {"ushort", Type::U16}, {"uint16", Type::U16},
      {"int", Type::I32},   {"int32", Type::I32},   {"uint", Type::U32},   {"uint32", Type::U32},
      {"float", Type::F32}, {"float32", Type::F32}, {"double", Type::F64}, {"float64", Type::F64}};
  for (const auto& [n, t] : kTypes)
    if (n == name) {
      type = t;
      return true;
    }
  return false;
}

size_t sizeOf(Type type) {
  switch (type) {
    case Type::I8:
    case Type::U8:
      return 1;
    case Type::I16:
    case Type::U16:
      return 2;
    case Type::I32:
    case Type::U32:
    case Type::F32:
      return 4;
    case Type::F64:
      return 8;
  }
  return 0;
}

bool isWhole(Type type) { return type != Type::F32 && type != Type::F64; }

struct Property {
  std::string name;
  Type type = Type::F32;  // the values' type (a list's entries)
  bool list = false;
  Type countType = Type::U8;  // a list's count
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  std::int64_t line = 0;  // of its header line
};

enum class Format { Ascii, LittleEndian, BigEndian };

struct Header {
  Format format = Format::Ascii;
  std::vector<Element> elements;
  size_t bodyStart = 0;       // byte offset of the first element
  std::int64_t bodyLine = 0;  // line number of the first element (ASCII)
};

/// Splits the header (up to and including the end_header line) into lines; refuses a
/// header with no end_header line or with bytes that are not text in it.
Header readPlyHeader(std::string_view bytes) {
  if (!startsLikePly(bytes.substr(0, bytes.find('\n'))))
    refuse("not a PLY file: it must start with a line 'ply', got " + quoted(bytes.substr(0, bytes.find('\n'))));
  // Lines end at '\n', '\r' or "\r\n". The end_header line is found first (storing
  // nothing: a damaged file may have no end), so that a header cut short says so whatever
  // else is wrong with it; a NUL ends a line there too (as it does for assimp's reader), and
  // is then refused as a byte that is not text.
  const auto lineEnd = [&](size_t from) {
    const size_t end = bytes.find_first_of(std::string_view("\n\r\0", 3), from);
    return end == std::string_view::npos ? bytes.size() : end;
  };
  const auto nextLine = [&](size_t end) {
    size_t next = end + 1;
    if (end < bytes.size() && bytes[end] == '\r' && next < bytes.size() && bytes[next] == '\n') ++next;
    return next;
  };
  size_t bodyStart = std::string_view::npos;
  for (size_t pos = 0; pos < bytes.size();) {
    const size_t end = lineEnd(pos);
    const std::string_view line = bytes.substr(pos, end - pos);
    pos = nextLine(end);
    const size_t start = line.find_first_not_of(" \t");
    if (start != std::string_view::npos && line.substr(start).substr(0, 10) == "end_header" &&
        line.find_first_not_of(" \t", start + 10) == std::string_view::npos) {
      bodyStart = std::min(pos, bytes.size());
      break;
    }
  }
  if (bodyStart == std::string_view::npos)
    refuse("PLY header has no end_header line (the file is truncated or not a PLY file)");
  std::vector<std::string_view> lines;
  std::vector<bool> endsWithNul;
  for (size_t pos = 0; pos < bodyStart;) {
    const size_t end = lineEnd(pos);
    lines.push_back(bytes.substr(pos, end - pos));
    endsWithNul.push_back(end < bytes.size() && bytes[end] == '\0');
    pos = nextLine(end);
  }
  for (size_t n = 0; n < lines.size(); ++n) {
    int bad = endsWithNul[n] ? 0 : -1;
    // Comments may be UTF-8 (a name with an accent); keywords, types and counts are ASCII.
    const size_t start = lines[n].find_first_not_of(" \t");
    const std::string_view first = start == std::string_view::npos ? std::string_view() : lines[n].substr(start);
    const bool comment = first.substr(0, 8) == "comment " || first.substr(0, 8) == "comment\t" ||
                         first.substr(0, 9) == "obj_info " || first.substr(0, 9) == "obj_info\t";
    for (const char c : lines[n]) {
      const unsigned char u = static_cast<unsigned char>(c);
      if ((u < 32 && u != '\t') || u == 127 || (u > 127 && !comment)) {
        bad = u;
        break;
      }
    }
    if (bad >= 0) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%02x", static_cast<unsigned>(bad));
      refuse(std::string("PLY header has a byte that is not text (") + hex + " in line " + std::to_string(n + 1) +
             "): the file is damaged or not a PLY file");
    }
  }

  Header header;
  header.bodyStart = bodyStart;
  header.bodyLine = static_cast<std::int64_t>(lines.size()) + 1;
  bool haveFormat = false;
  for (size_t n = 0; n < lines.size(); ++n) {
    const std::string where = "PLY header line " + std::to_string(n + 1) + ": ";
    Tokens tokens(lines[n]);
    const std::string_view keyword = tokens.next();
    if (n == 0) {
      if (keyword != "ply" || !tokens.next().empty())
        refuse("not a PLY file: it must start with a line 'ply', got " + quoted(lines[0]));
      continue;
    }
    if (keyword.empty() || keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") break;
    if (keyword == "format") {
      const std::string_view name = tokens.next();
      const std::string_view version = tokens.next();
      if (name == "ascii")
        header.format = Format::Ascii;
      else if (name == "binary_little_endian")
        header.format = Format::LittleEndian;
      else if (name == "binary_big_endian")
        header.format = Format::BigEndian;
      else
        refuse(where + "format must be ascii, binary_little_endian or binary_big_endian, got " + quoted(name));
      if (version != "1.0") refuse(where + "format version must be 1.0, got " + quoted(version));
      haveFormat = true;
    } else if (keyword == "element") {
      Element element;
      element.name = std::string(tokens.next());
      const std::string_view count = tokens.next();
      std::int64_t value = 0;
      if (element.name.empty() || !parseWhole(count, value) || value < 0 || !tokens.next().empty())
        refuse(where + "an element line is 'element <name> <count>' with a whole count >= 0, got " + quoted(lines[n]));
      element.count = static_cast<std::uint64_t>(value);
      element.line = static_cast<std::int64_t>(n + 1);
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) refuse(where + "a property before any element");
      Property property;
      std::string_view type = tokens.next();
      if (type == "list") {
        property.list = true;
        const std::string_view countType = tokens.next();
        if (!typeNamed(countType, property.countType) || !isWhole(property.countType))
          refuse(where + "a list's count type must be a whole-number type (uchar, ushort, uint, ...), got " +
                 quoted(countType));
        type = tokens.next();
      }
      if (!typeNamed(type, property.type))
        refuse(where +
               "property type must be one of char uchar short ushort int uint float double (or int8 ... "
               "float64), got " +
               quoted(type));
      property.name = std::string(tokens.next());
      if (property.name.empty() || !tokens.next().empty())
        refuse(where + "a property line is 'property <type> <name>' or 'property list <type> <type> <name>', got " +
               quoted(lines[n]));
      header.elements.back().properties.push_back(std::move(property));
    } else {
      refuse(where + "unknown keyword " + quoted(keyword) +
             " (a header has format, element, property, comment, obj_info and end_header lines)");
    }
  }
  if (!haveFormat) refuse("PLY header has no format line");
  return header;
}

/// Where the positions and the corner lists are, in the vertex and face elements.
struct Layout {
  int vertexElement = -1, faceElement = -1;
  std::array<int, 3> xyz{-1, -1, -1};
  int corners = -1;
};

Layout layoutOf(const Header& header) {
  static constexpr char kAxes[] = "xyz";
  Layout layout;
  for (size_t e = 0; e < header.elements.size(); ++e) {
    const Element& element = header.elements[e];
    const std::string where = "PLY header line " + std::to_string(element.line) + ": ";
    if (element.name == "vertex") {
      if (layout.vertexElement >= 0) refuse(where + "a second 'vertex' element");
      layout.vertexElement = static_cast<int>(e);
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const Property& property = element.properties[p];
        for (int axis = 0; axis < 3; ++axis)
          if (property.name == std::string_view(&kAxes[axis], 1)) {
            if (property.list) refuse(where + "vertex property '" + property.name + "' must be a number, not a list");
            if (layout.xyz[axis] >= 0) refuse(where + "vertex property '" + property.name + "' appears twice");
            layout.xyz[axis] = static_cast<int>(p);
          }
      }
      for (int axis = 0; axis < 3; ++axis)
        if (layout.xyz[axis] < 0)
          refuse(where + "the vertex element has no property '" + std::string(1, kAxes[axis]) + "'");
    } else if (element.name == "face") {
      if (layout.faceElement >= 0) refuse(where + "a second 'face' element");
      layout.faceElement = static_cast<int>(e);
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const Property& property = element.properties[p];
        if (property.name != "vertex_indices" && property.name != "vertex_index") continue;
        if (layout.corners >= 0) refuse(where + "the face element lists its vertex indices twice");
        if (!property.list || !isWhole(property.type))
          refuse(where + "face property '" + property.name + "' must be a list of whole numbers");
        layout.corners = static_cast<int>(p);
      }
      if (layout.corners < 0)
        refuse(where + "the face element has no 'vertex_indices' (or 'vertex_index') list property");
    }
  }
  if (layout.vertexElement < 0) refuse("PLY header has no 'vertex' element");
  return layout;
}

/// The fewest bytes one entry of `element` takes after the header: for a binary file the
/// fixed-size properties and the lists' counts; for an ASCII file one character and one
/// separator per property (a list at least its count).
std::uint64_t minimumBytes(const Element& element, Format format) {
  std::uint64_t bytes = 0;
  for (const Property& property : element.properties)
    bytes += format == Format::Ascii ? 2 : sizeOf(property.list ? property.countType : property.type);
  return bytes;
}

/// Reads the values of a PLY body, ASCII or binary, one at a time.
class PlyBody {
 public:
  PlyBody(std::string_view body, size_t header, Format format, std::int64_t firstLine)
      : body_(body), header_(header), format_(format), tokens_(body, firstLine) {}

  /// The next value, of type `type`; what() names it for messages (called only on an error,
  /// so that reading a value builds no string).
  template <class What>
  double value(Type type, What&& what) {
    if (format_ == Format::Ascii) {
      const std::string_view token = tokens_.next();
      if (token.empty()) refuse("PLY file ends before " + what());
      double v = 0;
      if (!parseNumber(token, v))
        refuse("PLY line " + std::to_string(tokens_.line()) + ": " + what() + " must be a number, got " +
               quoted(token));
      // A whole number within +-2^53 (where doubles hold every integer): "nan", "inf" and
      // 1e19 are not counts or indices.
      if (isWhole(type) && !(std::abs(v) <= 0x1p53 && std::trunc(v) == v))
        refuse("PLY line " + std::to_string(tokens_.line()) + ": " + what() + " must be a whole number, got " +
               quoted(token));
      return v;
    }
    const size_t size = sizeOf(type);
    if (body_.size() - pos_ < size)
      refuse("PLY file ends before " + what() + " (byte " + std::to_string(header_ + pos_) + " of the file)");
    // The value's bits, most significant byte first, whatever the file's byte order.
    std::uint64_t bits = 0;
    for (size_t k = 0; k < size; ++k) {
      const size_t at = format_ == Format::BigEndian ? k : size - 1 - k;
      bits = (bits << 8) | static_cast<unsigned char>(body_[pos_ + at]);
    }
    pos_ += size;
    switch (type) {
      case Type::I8:
        return static_cast<double>(static_cast<std::int8_t>(static_cast<std::uint8_t>(bits)));
      case Type::U8:
        return static_cast<double>(bits);
      case Type::I16:
        return static_cast<double>(static_cast<std::int16_t>(static_cast<std::uint16_t>(bits)));
      case Type::U16:
        return static_cast<double>(bits);
      case Type::I32:
        return static_cast<double>(static_cast<std::int32_t>(static_cast<std::uint32_t>(bits)));
      case Type::U32:
        return static_cast<double>(bits);
      case Type::F32:
        return static_cast<double>(std::bit_cast<float>(static_cast<std::uint32_t>(bits)));
      case Type::F64:
        return std::bit_cast<double>(bits);
    }
    return 0;
  }

  /// Refuses values left over after the last element (the header's counts are then smaller
  /// than the data: reading on would lose them). A binary file may end in white space (a
  /// trailing newline), nothing else.
  void expectEnd() {
    if (format_ != Format::Ascii) {
      size_t extra = pos_;
      while (extra < body_.size() && isSpace(body_[extra])) ++extra;
      if (extra < body_.size())
        refuse("PLY file: " + std::to_string(body_.size() - pos_) + " bytes after the last element the header " +
               "declares, from byte " + std::to_string(header_ + pos_) +
               " of the file (its counts are smaller than the data)");
      return;
    }
    const std::string_view token = tokens_.next();
    if (!token.empty())
      refuse("PLY line " + std::to_string(tokens_.line()) + ": " + quoted(token) +
             " after the last element the header declares (its counts are smaller than the data)");
  }

 private:
  std::string_view body_;
  size_t header_;  // the header's bytes, before the body
  Format format_;
  Tokens tokens_;
  size_t pos_ = 0;
};

}  // namespace

bool startsLikePly(std::string_view head) {
  const size_t start = head.find_first_not_of(" \t");
  if (start == std::string_view::npos || head.size() - start < 3) return false;
  return lower(head[start]) == 'p' && lower(head[start + 1]) == 'l' && lower(head[start + 2]) == 'y';
}

std::vector<PolygonMesh> readPly(std::string_view bytes) {
  const Header header = readPlyHeader(bytes);
  const Layout layout = layoutOf(header);
  const std::string_view body = bytes.substr(header.bodyStart);

  // Every declared count against the bytes that are there, before anything is allocated.
  std::uint64_t needed = 0;
  for (const Element& element : header.elements) {
    const std::uint64_t each = minimumBytes(element, header.format);
    if (element.count > 0 && each == 0)
      refuse("PLY header line " + std::to_string(element.line) + ": element '" + element.name + "' has " +
             std::to_string(element.count) + " entries but no properties");
    const std::uint64_t room = body.size() - std::min<std::uint64_t>(needed, body.size());
    if (each > 0 && element.count > room / each)
      refuse("PLY header line " + std::to_string(element.line) + ": " + std::to_string(element.count) + " '" +
             element.name + "' entries need at least " + std::to_string(each) + " bytes each, but only " +
             std::to_string(room) + " bytes of the file are left for them (it is truncated, or the count is wrong)");
    needed += element.count * each;
  }
  const std::uint64_t vertexCount = header.elements[static_cast<size_t>(layout.vertexElement)].count;
  if (vertexCount > std::numeric_limits<std::int32_t>::max())
    refuse("PLY file has " + std::to_string(vertexCount) + " vertices; weft reads up to 2147483647");

  PolygonMesh mesh;
  mesh.xyz.reserve(3 * vertexCount);
  std::uint64_t droppedFaces = 0;
  PlyBody reader(body, header.bodyStart, header.format, header.bodyLine);
  for (size_t e = 0; e < header.elements.size(); ++e) {
    const Element& element = header.elements[e];
    const bool vertices = static_cast<int>(e) == layout.vertexElement;
    const bool faces = static_cast<int>(e) == layout.faceElement;
    for (std::uint64_t i = 0; i < element.count; ++i) {
      std::array<double, 3> position{};
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const Property& property = element.properties[p];
        const auto what = [&] { return element.name + " " + std::to_string(i) + " property '" + property.name + "'"; };
        if (!property.list) {
          double v = reader.value(property.type, what);
          if (property.type == Type::F32) v = asDeclaredFloat(v);  // (an ASCII value as the header declares it)
          if (vertices)
            for (int axis = 0; axis < 3; ++axis)
              if (layout.xyz[axis] == static_cast<int>(p)) position[axis] = v;
          continue;
        }
        const double count = reader.value(property.countType, [&] { return "the count of " + what(); });
        if (count < 0)
          refuse("PLY " + what() + ": a list's count must be >= 0, got " +
                 std::to_string(static_cast<long long>(count)));
        const bool corners = faces && layout.corners == static_cast<int>(p);
        if (corners && count > kMaxPolygonCorners)
          refuse("PLY face " + std::to_string(i) + " has " + std::to_string(static_cast<long long>(count)) +
                 " corners; weft reads polygons of up to " + std::to_string(kMaxPolygonCorners));
        // A list longer than the bytes left is refused by value() when they run out.
        for (std::uint64_t k = 0; k < static_cast<std::uint64_t>(count); ++k) {
          const double v = reader.value(property.type, [&] { return "entry " + std::to_string(k) + " of " + what(); });
          if (!corners) continue;
          if (v < 0 || v >= static_cast<double>(vertexCount))
            refuse("PLY face " + std::to_string(i) + " corner " + std::to_string(k) +
                   ": vertex index must be >= 0 and < " + std::to_string(vertexCount) + " (the vertex count), got " +
                   std::to_string(static_cast<long long>(v)));
          mesh.indices.push_back(static_cast<std::uint32_t>(v));
        }
        if (corners) {
          if (count > 0)
            mesh.faceSizes.push_back(static_cast<std::uint32_t>(count));
          else
            ++droppedFaces;
        }
      }
      if (vertices)
        for (const double v : position) mesh.xyz.push_back(v);
    }
  }
  reader.expectEnd();
  mesh.emptyFaces = droppedFaces;
  if (mesh.faceSizes.empty())
    refuse("no triangles: the PLY file has " + std::to_string(vertexCount) + " vertices and " +
           (layout.faceElement < 0 ? std::string("no face element")
            : droppedFaces == 0    ? std::string("0 faces")
                                   : std::to_string(droppedFaces) + " faces, none with a corner"));
  std::vector<PolygonMesh> meshes;
  meshes.push_back(std::move(mesh));
  return meshes;
}

// ---------------------------------------------------------------------------------------
// STL

namespace {

constexpr size_t kStlHeader = 84, kStlFacet = 50;
static_assert(std::endian::native == std::endian::little, "binary STL floats are copied as they are: little endian");

/// The triangle count of a binary STL's header (bytes 80-83, little endian).
std::uint32_t stlCount(std::string_view bytes) {
  std::uint32_t count = 0;
  for (int k = 3; k >= 0; --k) count = (count << 8) | static_cast<unsigned char>(bytes[80 + static_cast<size_t>(k)]);
  return count;
}

/// Whether a file of `size` bytes starting with `head` is a binary STL file.
bool isBinaryStl(std::string_view head, std::uint64_t size) {
  if (size < kStlHeader || head.size() < kStlHeader) return false;
  return size == kStlHeader + kStlFacet * static_cast<std::uint64_t>(stlCount(head));
}
bool isBinaryStl(std::string_view bytes) { return isBinaryStl(bytes, bytes.size()); }

bool startsWithSolid(std::string_view bytes) {
  const size_t start = bytes.find_first_not_of(" \t\r\n");
  return start != std::string_view::npos && bytes.size() - start >= 5 &&
         equalsIgnoringCase(bytes.substr(start, 5), "solid") &&
         (bytes.size() - start == 5 || isSpace(bytes[start + 5]));
}

std::vector<PolygonMesh> readBinaryStl(std::string_view bytes) {
  const std::uint32_t count = stlCount(bytes);
  if (count == 0) refuse("no triangles: the binary STL file declares 0 triangles");
  if (count > static_cast<std::uint32_t>(std::numeric_limits<std::int32_t>::max() / 3))
    refuse("binary STL file has " + std::to_string(count) + " triangles; weft reads up to 715827882");
  PolygonMesh mesh;
  mesh.xyz.resize(9 * static_cast<size_t>(count));
  mesh.faceSizes.assign(count, 3);
  mesh.indices.resize(3 * static_cast<size_t>(count));
  for (std::uint32_t f = 0; f < count; ++f) {
    // 12 floats: the normal (not used), then the three corners; then 2 attribute bytes.
    float corners[9];
    std::memcpy(corners, bytes.data() + kStlHeader + kStlFacet * f + 12, 36);
    for (int k = 0; k < 9; ++k) mesh.xyz[9 * static_cast<size_t>(f) + static_cast<size_t>(k)] = corners[k];
    for (std::uint32_t k = 0; k < 3; ++k) mesh.indices[3 * static_cast<size_t>(f) + k] = 3 * f + k;
  }
  std::vector<PolygonMesh> meshes;
  meshes.push_back(std::move(mesh));
  return meshes;
}

std::vector<PolygonMesh> readAsciiStl(std::string_view bytes) {
  Tokens tokens(bytes);
  std::vector<PolygonMesh> meshes;
  std::uint64_t facets = 0;
  const auto at = [&] { return "ASCII STL line " + std::to_string(tokens.line()) + ": "; };
  const auto expect = [&](std::string_view keyword) {
    const std::string_view token = tokens.next();
    if (!equalsIgnoringCase(token, keyword))
      refuse(at() + "expected '" + std::string(keyword) + "', got " +
             (token.empty() ? "the end of the file" : quoted(token)));
  };
  const auto number = [&](const char* what) {
    const std::string_view token = tokens.next();
    double v = 0;
    if (!parseNumber(token, v))
      refuse(at() + what + " must be a number, got " + (token.empty() ? "the end of the file" : quoted(token)));
    return v;
  };
  std::string_view token = tokens.next();
  while (!token.empty()) {
    if (!equalsIgnoringCase(token, "solid")) refuse(at() + "expected 'solid', got " + quoted(token));
    tokens.skipLine();  // the solid's name
    PolygonMesh mesh;
    for (;;) {
      token = tokens.next();
      if (token.empty()) break;  // a file cut after its last facet: nothing is lost
      if (equalsIgnoringCase(token, "endsolid")) {
        tokens.skipLine();
        token = tokens.next();
        break;
      }
      if (!equalsIgnoringCase(token, "facet")) refuse(at() + "expected 'facet' or 'endsolid', got " + quoted(token));
      expect("normal");
      for (const char* axis : {"the facet normal's x", "the facet normal's y", "the facet normal's z"}) number(axis);
      expect("outer");
      expect("loop");
      const std::uint32_t first = static_cast<std::uint32_t>(mesh.vertexCount());
      for (int k = 0; k < 3; ++k) {
        expect("vertex");
        for (const char* axis : {"a vertex's x", "a vertex's y", "a vertex's z"}) mesh.xyz.push_back(number(axis));
      }
      token = tokens.next();
      if (equalsIgnoringCase(token, "vertex"))
        refuse(at() + "facet " + std::to_string(facets) + " has more than 3 vertices (STL facets are triangles)");
      if (!equalsIgnoringCase(token, "endloop"))
        refuse(at() + "expected 'endloop', got " + (token.empty() ? "the end of the file" : quoted(token)));
      expect("endfacet");
      if (mesh.vertexCount() > static_cast<size_t>(std::numeric_limits<std::int32_t>::max()) - 3)
        refuse(at() + "more than 2147483647 vertices");
      mesh.faceSizes.push_back(3);
      for (std::uint32_t k = 0; k < 3; ++k) mesh.indices.push_back(first + k);
      ++facets;
    }
    if (!mesh.faceSizes.empty()) meshes.push_back(std::move(mesh));
  }
  if (meshes.empty()) refuse("no triangles: the ASCII STL file has no facets");
  return meshes;
}

}  // namespace

bool looksLikeStl(std::string_view head, std::uint64_t size) {
  return isBinaryStl(head, size) || startsWithSolid(head);
}

std::vector<PolygonMesh> readStl(std::string_view bytes) {
  // A binary file may start with "solid" too (some exporters write it in the 80-byte
  // header): its size decides first, as for assimp.
  if (isBinaryStl(bytes)) return readBinaryStl(bytes);
  if (startsWithSolid(bytes)) return readAsciiStl(bytes);
  if (bytes.size() >= kStlHeader) {
    const std::uint32_t count = stlCount(bytes);
    refuse("not an STL file: it does not start with 'solid' (ASCII), and as a binary STL its header declares " +
           std::to_string(count) + " triangles, which take " +
           std::to_string(kStlHeader + kStlFacet * static_cast<std::uint64_t>(count)) + " bytes, but the file has " +
           std::to_string(bytes.size()));
  }
  refuse("not an STL file: it does not start with 'solid' (ASCII) and is shorter than a binary STL's 84-byte header (" +
         std::to_string(bytes.size()) + " bytes)");
}

// ---------------------------------------------------------------------------------------
// OBJ

const char* ownFormatByName(std::string_view name) {
  const size_t dot = name.find_last_of("./");
  if (dot == std::string_view::npos || name[dot] != '.') return nullptr;
  const std::string_view extension = name.substr(dot + 1);
  for (const char* format : {"ply", "stl", "obj"})
    if (equalsIgnoringCase(extension, format)) return format;
  return nullptr;
}

bool looksLikeObj(std::string_view head) {
  // The first statement that is not a comment: an OBJ keyword followed by white space.
  static constexpr std::string_view kKeywords[] = {"v", "vt", "vn", "vp", "f",      "l",
                                                   "p", "o",  "g",  "s",  "mtllib", "usemtl"};
  size_t pos = 0;
  while (pos < head.size()) {
    while (pos < head.size() && isSpace(head[pos])) ++pos;
    if (pos < head.size() && head[pos] == '#') {
      while (pos < head.size() && head[pos] != '\n' && head[pos] != '\r') ++pos;
      continue;
    }
    size_t end = pos;
    while (end < head.size() && !isSpace(head[end])) ++end;
    if (end == head.size()) return false;  // (a keyword cut by the end of the head says nothing)
    const std::string_view word = head.substr(pos, end - pos);
    for (const std::string_view keyword : kKeywords)
      if (word == keyword) return true;
    return false;
  }
  return false;
}

std::vector<PolygonMesh> readObj(std::string_view bytes) {
  PolygonMesh mesh;
  constexpr std::uint64_t kMaxVertices = static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max());
  // The largest positive index used, checked against the vertex count at the end (a face may
  // name a vertex the file lists after it), with where it was.
  std::int64_t largest = 0, largestLine = 0;
  std::int64_t lineNumber = 0;
  std::string logical;  // a line with its continuations ("\" at the end) joined
  size_t pos = 0;
  std::vector<std::string_view> tokens;
  while (pos < bytes.size()) {
    // The next logical line: physical lines end in \n, \r\n or a lone \r; a comment runs to
    // the end of its physical line; a line ending in a backslash continues on the next.
    logical.clear();
    const std::int64_t firstLine = lineNumber + 1;
    for (;;) {
      size_t end = pos;
      while (end < bytes.size() && bytes[end] != '\n' && bytes[end] != '\r') ++end;
      std::string_view line = bytes.substr(pos, end - pos);
      pos = end < bytes.size() && bytes[end] == '\r' && end + 1 < bytes.size() && bytes[end + 1] == '\n' ? end + 2
                                                                                                         : end + 1;
      ++lineNumber;
      const size_t hash = line.find('#');
      if (hash != std::string_view::npos) line = line.substr(0, hash);
      const bool continued = !line.empty() && line.back() == '\\';
      if (continued) line.remove_suffix(1);
      logical.append(line);
      if (!continued || pos >= bytes.size()) break;
      logical.push_back(' ');
    }
    const std::string_view text = logical;
    tokens.clear();
    for (size_t k = 0; k < text.size();) {
      while (k < text.size() && isSpace(text[k])) ++k;
      const size_t start = k;
      while (k < text.size() && !isSpace(text[k])) ++k;
      if (k > start) tokens.push_back(text.substr(start, k - start));
    }
    if (tokens.empty()) continue;
    const std::string at = "OBJ line " + std::to_string(firstLine) + ": ";
    const std::string_view keyword = tokens[0];
    if (keyword == "v") {
      const size_t n = tokens.size() - 1;
      if (n != 3 && n != 4 && n != 6)
        refuse(at + "a vertex has " + std::to_string(n) +
               " numbers; expected 3 (x y z), 4 (x y z w) or 6 (x y z r g b)");
      double value[4] = {0, 0, 0, 1};
      for (size_t k = 0; k < n; ++k) {
        double v = 0;
        if (!parseNumber(tokens[k + 1], v))
          refuse(at + "vertex " + std::to_string(mesh.vertexCount()) + " entry " + std::to_string(k) +
                 " must be a number, got " + quoted(tokens[k + 1]));
        if (k < 3 || (k == 3 && n == 4)) value[k] = v;
      }
      if (value[3] != 1)
        refuse(at + "vertex " + std::to_string(mesh.vertexCount()) + " has w = " + detail::number(value[3]) +
               "; weft reads vertices with w = 1 (dividing by w would change the file's coordinates)");
      if (mesh.vertexCount() >= kMaxVertices) refuse(at + "more than 2147483647 vertices");
      mesh.xyz.insert(mesh.xyz.end(), value, value + 3);
    } else if (keyword == "f" || keyword == "l" || keyword == "p") {
      const size_t count = tokens.size() - 1;
      if (count == 0) refuse(at + "'" + std::string(keyword) + "' with no vertex");
      if (keyword == "p") {
        mesh.points += count;
        continue;
      }
      if (keyword == "l") {
        ++mesh.lines;
        continue;
      }
      if (count > kMaxPolygonCorners)
        refuse(at + "a face has " + std::to_string(count) + " corners; weft reads polygons of up to " +
               std::to_string(kMaxPolygonCorners));
      for (size_t k = 0; k < count; ++k) {
        const std::string_view token = tokens[k + 1];
        const std::string_view vertex = token.substr(0, token.find('/'));
        std::int64_t index = 0;
        const bool signs = vertex.size() > 1 && vertex[0] == '+' && (vertex[1] == '-' || vertex[1] == '+');
        if (signs || !parseWhole(vertex, index) || index == 0)
          refuse(at + "corner " + std::to_string(k) + " of a face must be a vertex number (1 is the first, -1 the " +
                 "last read), got " + quoted(token));
        const auto read = static_cast<std::int64_t>(mesh.vertexCount());
        if (index < 0) {
          if (index < -read)
            refuse(at + "corner " + std::to_string(k) + " of a face is vertex " + std::to_string(index) + ", but " +
                   std::to_string(read) + " vertices are read so far");
          index = read + index;
        } else {
          if (index > static_cast<std::int64_t>(kMaxVertices))
            refuse(at + "corner " + std::to_string(k) + " of a face is vertex " + std::to_string(index) +
                   "; weft reads up to 2147483647 vertices");
          index -= 1;
          if (index + 1 > largest) {
            largest = index + 1;
            largestLine = firstLine;
          }
        }
        mesh.indices.push_back(static_cast<std::uint32_t>(index));
      }
      mesh.faceSizes.push_back(static_cast<std::uint32_t>(count));
    }
    // Anything else (vt, vn, o, g, s, usemtl, mtllib, ...) holds nothing weft uses.
  }
  if (largest > static_cast<std::int64_t>(mesh.vertexCount()))
    refuse("OBJ line " + std::to_string(largestLine) + ": a face names vertex " + std::to_string(largest) +
           ", but the file has " + std::to_string(mesh.vertexCount()) + " vertices");
  if (mesh.faceSizes.empty())
    refuse("no triangles: the OBJ file has " + counted(mesh.vertexCount(), "vertex", "vertices") + ", " +
           counted(mesh.points, "point", "points") + ", " + counted(mesh.lines, "line", "lines") + " and no faces");
  std::vector<PolygonMesh> meshes;
  meshes.push_back(std::move(mesh));
  return meshes;
}

// ---------------------------------------------------------------------------------------
// Polygons to triangles

void triangulatePolygon(const std::vector<double>& xyz, const std::uint32_t* corners, std::uint32_t count,
                        std::vector<std::array<std::uint32_t, 3>>& out) {
  if (count < 3) return;
  if (count == 3) {
    out.push_back({corners[0], corners[1], corners[2]});
    return;
  }
  const auto at = [&](std::uint32_t k, int axis) { return xyz[3 * static_cast<size_t>(corners[k]) + axis]; };
  // Newell's normal: its components are the polygon's areas projected on the three planes.
  double normal[3] = {0, 0, 0};
  for (std::uint32_t k = 0; k < count; ++k) {
    const std::uint32_t j = k + 1 == count ? 0 : k + 1;
    normal[0] += (at(k, 1) - at(j, 1)) * (at(k, 2) + at(j, 2));
    normal[1] += (at(k, 2) - at(j, 2)) * (at(k, 0) + at(j, 0));
    normal[2] += (at(k, 0) - at(j, 0)) * (at(k, 1) + at(j, 1));
  }
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(normal[a]) > std::abs(normal[axis])) axis = a;
  if (!(std::abs(normal[axis]) > 0) || !std::isfinite(normal[axis])) {  // no plane to cut in: a fan
    for (std::uint32_t k = 1; k + 1 < count; ++k) out.push_back({corners[0], corners[k], corners[k + 1]});
    return;
  }
  // In the plane across `axis` ((u, v) = the next two axes, so that the 2D cross product is
  // the normal's `axis` component), turned so that the polygon runs counter-clockwise.
  const int ua = (axis + 1) % 3, va = (axis + 2) % 3;
  const double turn = normal[axis] > 0 ? 1 : -1;
  std::vector<double> u(count), v(count);
  for (std::uint32_t k = 0; k < count; ++k) {
    u[k] = at(k, ua);
    v[k] = turn * at(k, va);
  }
  const auto cross = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    return (u[b] - u[a]) * (v[c] - v[a]) - (v[b] - v[a]) * (u[c] - u[a]);
  };
  std::vector<std::uint32_t> prev(count), next(count);
  for (std::uint32_t k = 0; k < count; ++k) {
    prev[k] = k == 0 ? count - 1 : k - 1;
    next[k] = k + 1 == count ? 0 : k + 1;
  }
  // Only a reflex corner can lie inside an ear. The list is pruned as corners are cut off or
  // turn convex (cutting an ear off a simple polygon turns no corner reflex).
  std::vector<std::uint32_t> reflex;
  std::vector<char> isReflex(count, 0);
  for (std::uint32_t k = 0; k < count; ++k)
    if (cross(prev[k], k, next[k]) <= 0) {
      reflex.push_back(k);
      isReflex[k] = 1;
    }
  const auto same = [&](std::uint32_t a, std::uint32_t b) { return u[a] == u[b] && v[a] == v[b]; };
  // The ear tests' work is bounded (a polygon crossing itself, built against this, could
  // take n^3 steps): past the budget, or after a whole round with no ear, the rest is a fan.
  std::uint64_t budget = 64 * static_cast<std::uint64_t>(count) * (reflex.size() + 16);
  const auto isEar = [&](std::uint32_t b) {
    const std::uint32_t a = prev[b], c = next[b];
    if (!(cross(a, b, c) > 0)) return false;
    budget -= std::min<std::uint64_t>(budget, reflex.size() + 1);
    for (const std::uint32_t r : reflex) {
      if (r == a || r == b || r == c || same(r, a) || same(r, b) || same(r, c)) continue;
      if (cross(a, b, r) >= 0 && cross(b, c, r) >= 0 && cross(c, a, r) >= 0) return false;
    }
    return true;
  };
  const auto prune = [&](std::uint32_t k) {  // k was cut off, or may have turned convex
    if (isReflex[k] && (next[prev[k]] != k || cross(prev[k], k, next[k]) > 0)) {
      isReflex[k] = 0;
      reflex.erase(std::find(reflex.begin(), reflex.end(), k));
    }
  };
  std::uint32_t remaining = count, k = 0, tried = 0;
  while (remaining > 3) {
    if (tried >= remaining || budget == 0) {  // no ear left to find: the rest as a fan
      for (std::uint32_t j = next[k]; next[j] != k; j = next[j])
        out.push_back({corners[k], corners[j], corners[next[j]]});
      return;
    }
    if (isEar(k)) {
      const std::uint32_t before = prev[k], after = next[k];
      out.push_back({corners[before], corners[k], corners[after]});
      next[before] = after;
      prev[after] = before;
      prune(k);
      prune(before);
      prune(after);
      --remaining;
      tried = 0;
      k = before;  // the corner before may have become an ear
    } else {
      k = next[k];
      ++tried;
    }
  }
  out.push_back({corners[prev[k]], corners[k], corners[next[k]]});
}

}  // namespace weft::io_detail
