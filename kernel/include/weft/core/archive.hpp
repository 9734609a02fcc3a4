// weft/core/archive.hpp — the bytes of a checkpoint: values, vectors and arrays written in
// order, read back in the same order with every size checked.
//
// Design note
// -----------
// Simulation::save writes what a later step depends on through an ArchiveWriter (the
// state, the integrator's carry-over, the rigid bodies' warm-start caches) and load reads
// it back through an ArchiveReader, component by component, in the same order. The bytes
// are the machine's own (little-endian x86-64, the compiler's layout of the kernel's plain
// structs): a checkpoint is for resuming on a build of the same weft version, which the
// file's header records and Simulation::load checks, not an exchange format. A reader
// never trusts a count: before it allocates or copies it checks that the bytes are there,
// and a section tag before each component says where a mismatch is. Every failure throws
// std::runtime_error("checkpoint '<source>': <what>").
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "weft/core/types.hpp"

namespace weft {

namespace archive_detail {
template <class T>
struct IsVector : std::false_type {};
template <class T, class A>
struct IsVector<std::vector<T, A>> : std::true_type {};
template <class T, class = void>
struct IsDynamicEigen : std::false_type {};
template <class T>
struct IsDynamicEigen<T, std::void_t<decltype(T::SizeAtCompileTime)>>
    : std::bool_constant<T::SizeAtCompileTime == Eigen::Dynamic> {};
}  // namespace archive_detail

/// 64-bit FNV-1a of `size` bytes, continuing from `hash` (the checkpoint's checksum and
/// model fingerprint).
std::uint64_t fnv1a64(const void* data, std::size_t size, std::uint64_t hash = 14695981039346656037ull);

class ArchiveWriter {
 public:
  explicit ArchiveWriter(std::string& out) : out_(&out) {}

  void bytes(const void* data, std::size_t size) {
    if (size > 0) out_->append(static_cast<const char*>(data), size);  // (an empty vector's data may be null)
  }
  /// A plain value (arithmetic, enum, a struct of such, a fixed-size Eigen type).
  template <class T>
  void value(const T& v) {
    static_assert(std::is_standard_layout_v<T>, "a checkpoint value must be plain data");
    bytes(static_cast<const void*>(&v), sizeof v);
  }
  template <class T>
  void vector(const std::vector<T>& v) {
    static_assert(std::is_standard_layout_v<T>, "a checkpoint vector must hold plain data");
    value(static_cast<std::uint64_t>(v.size()));
    bytes(static_cast<const void*>(v.data()), v.size() * sizeof(T));
  }
  /// A dynamic Eigen array or matrix: its shape, then its coefficients.
  template <class Derived>
  void array(const Eigen::PlainObjectBase<Derived>& a) {
    value(static_cast<std::int64_t>(a.rows()));
    value(static_cast<std::int64_t>(a.cols()));
    bytes(a.data(), static_cast<std::size_t>(a.size()) * sizeof(typename Derived::Scalar));
  }
  void text(const std::string& s) {
    value(static_cast<std::uint64_t>(s.size()));
    bytes(s.data(), s.size());
  }
  /// One field of a component's transfer function, the one piece of code that lists what a
  /// checkpoint holds in order, for writing and (with ArchiveReader::field) for reading:
  /// a vector, a dynamic Eigen array, or a plain value.
  template <class T>
  void field(const T& v, const char* /*what*/) {
    if constexpr (archive_detail::IsVector<T>::value)
      vector(v);
    else if constexpr (archive_detail::IsDynamicEigen<T>::value)
      array(v);
    else
      value(v);
  }
  /// A four-letter tag the reader checks (it names the component in a reader's message).
  void section(const char (&tag)[5]) { bytes(tag, 4); }
  std::size_t size() const { return out_->size(); }

 private:
  std::string* out_;
};

class ArchiveReader {
 public:
  ArchiveReader(std::string_view in, std::string source) : in_(in), source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& what) const;

  void bytes(void* data, std::size_t size) {
    if (size == 0) return;  // (an empty vector's data may be null)
    need(size);
    std::memcpy(data, in_.data() + at_, size);
    at_ += size;
  }
  template <class T>
  void value(T& v) {
    static_assert(std::is_standard_layout_v<T>, "a checkpoint value must be plain data");
    bytes(static_cast<void*>(&v), sizeof v);
  }
  template <class T>
  T value() {
    T v{};
    value(v);
    return v;
  }
  /// A bool: its byte must be 0 or 1 (any other is no bool, and refused).
  void flag(bool& b, const char* what) {
    unsigned char c = 0;
    bytes(&c, 1);
    if (c > 1) fail(std::string(what) + ": " + std::to_string(c) + " is not a bool");
    b = c == 1;
  }
  /// The same for the bool member at `offset` of a plain value read before.
  template <class T>
  void checkFlag(const T& v, std::size_t offset, const char* what) const {
    unsigned char c = 0;
    std::memcpy(&c, reinterpret_cast<const unsigned char*>(&v) + offset, 1);
    if (c > 1) fail(std::string(what) + ": " + std::to_string(c) + " is not a bool");
  }
  /// A vector of at most what the remaining bytes can hold (a count is never trusted).
  template <class T>
  void vector(std::vector<T>& v, const char* what) {
    const std::uint64_t count = value<std::uint64_t>();
    if (count > (in_.size() - at_) / (sizeof(T) > 0 ? sizeof(T) : 1))
      fail(std::string(what) + ": " + std::to_string(count) + " entries claimed, more than the file holds");
    v.resize(static_cast<std::size_t>(count));
    bytes(static_cast<void*>(v.data()), v.size() * sizeof(T));
  }
  /// A dynamic Eigen array whose shape must be `rows` x `cols` (the Simulation's own); with
  /// `finite`, every entry must be a finite number (an array the next step reads: a NaN in
  /// it would only surface steps later).
  template <class Derived>
  void array(Eigen::PlainObjectBase<Derived>& a, Index rows, Index cols, const char* what, bool finite = false) {
    const auto r = value<std::int64_t>(), c = value<std::int64_t>();
    if (r != rows || c != cols)
      fail(std::string(what) + ": " + std::to_string(r) + " x " + std::to_string(c) + " in the file, " +
           std::to_string(rows) + " x " + std::to_string(cols) + " in this simulation");
    a.resize(rows, cols);
    bytes(a.data(), static_cast<std::size_t>(a.size()) * sizeof(typename Derived::Scalar));
    if constexpr (std::is_floating_point_v<typename Derived::Scalar>) {
      if (finite && !a.allFinite())
        for (Index j = 0; j < cols; ++j)
          for (Index i = 0; i < rows; ++i)
            if (!std::isfinite(a(i, j)))
              fail(std::string(what) + ": entry (" + std::to_string(i) + ", " + std::to_string(j) + ") is " +
                   (std::isnan(a(i, j)) ? "nan" : "infinite") + ", not a finite number");
    }
  }
  std::string text(const char* what, std::size_t maxSize = 4096) {
    const std::uint64_t size = value<std::uint64_t>();
    if (size > maxSize || size > in_.size() - at_)
      fail(std::string(what) + ": a text of " + std::to_string(size) + " bytes claimed");
    std::string s(in_.substr(at_, static_cast<std::size_t>(size)));
    at_ += static_cast<std::size_t>(size);
    return s;
  }
  /// The reading side of ArchiveWriter::field: a dynamic Eigen array must have the shape
  /// the object already has (the Simulation's own).
  template <class T>
  void field(T& v, const char* what) {
    if constexpr (archive_detail::IsVector<T>::value)
      vector(v, what);
    else if constexpr (archive_detail::IsDynamicEigen<T>::value)
      array(v, v.rows(), v.cols(), what);
    else
      value(v);
  }
  void section(const char (&tag)[5]) {
    char got[4];
    bytes(got, 4);
    if (std::memcmp(got, tag, 4) != 0)
      fail(std::string("expected the section '") + tag + "' at byte " + std::to_string(at_ - 4) + ", found '" +
           printable(got) + "'");
  }
  std::size_t position() const { return at_; }
  std::size_t remaining() const { return in_.size() - at_; }
  const std::string& source() const { return source_; }

 private:
  void need(std::size_t size) const {
    if (size > in_.size() - at_)
      fail("truncated: " + std::to_string(size) + " more bytes needed at byte " + std::to_string(at_) + " of " +
           std::to_string(in_.size()));
  }
  static std::string printable(const char* tag);

  std::string_view in_;
  std::size_t at_ = 0;
  std::string source_;
};

}  // namespace weft
