#include "metrics/cloud_io.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>

#include "sim/demand.h"
#include "sim/log.h"
#include "sim/mesh.h"

namespace gd::metrics {
namespace {

using sim::InputError;

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

/// Reads one coordinate stored as float32 or float64 at `p`.
double read_scalar(const uint8_t* p, uint8_t datatype) {
  if (datatype == pcl::PCLPointField::FLOAT64) {
    double v;
    std::memcpy(&v, p, sizeof v);
    return v;
  }
  float v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

/// Copies the x, y, z fields of a PCL blob into a Cloud (non-finite points are kept here).
Cloud xyz_from_blob(const pcl::PCLPointCloud2& blob, const std::string& path) {
  const pcl::PCLPointField* f[3] = {nullptr, nullptr, nullptr};
  const char* names[3] = {"x", "y", "z"};
  for (const auto& field : blob.fields)
    for (int k = 0; k < 3; ++k)
      if (field.name == names[k]) f[k] = &field;
  for (int k = 0; k < 3; ++k) {
    if (!f[k])
      throw InputError(fmt::format("point cloud '{}' has no '{}' field; expected fields x y z",
                                   path, names[k]));
    if (f[k]->datatype != pcl::PCLPointField::FLOAT32 &&
        f[k]->datatype != pcl::PCLPointField::FLOAT64)
      throw InputError(fmt::format(
          "point cloud '{}': field '{}' is not float32 or float64 (PCL datatype {})", path,
          names[k], int(f[k]->datatype)));
  }
  for (int k = 0; k < 3; ++k)
    if (size_t(f[k]->offset) + (f[k]->datatype == pcl::PCLPointField::FLOAT64 ? 8 : 4) > blob.point_step)
      throw InputError(fmt::format("point cloud '{}': field '{}' lies outside its {}-byte point", path, names[k],
                                   blob.point_step));
  if (blob.height > 1 && size_t(blob.row_step) < size_t(blob.width) * blob.point_step)
    throw InputError(fmt::format("point cloud '{}': rows of {} bytes cannot hold {} points of {} bytes", path,
                                 blob.row_step, blob.width, blob.point_step));
  const size_t n = size_t(blob.width) * blob.height;
  const size_t need = n == 0 ? 0 : size_t(blob.height - 1) * blob.row_step + size_t(blob.width) * blob.point_step;
  if (blob.data.size() < need)
    throw InputError(fmt::format("point cloud '{}' is truncated ({} bytes of data for {} points)",
                                 path, blob.data.size(), n));
  Cloud out;
  out.reserve(n);
  for (uint32_t r = 0; r < blob.height; ++r) {
    for (uint32_t c = 0; c < blob.width; ++c) {
      const uint8_t* p = blob.data.data() + size_t(r) * blob.row_step + size_t(c) * blob.point_step;
      out.emplace_back(float(read_scalar(p + f[0]->offset, f[0]->datatype)),
                       float(read_scalar(p + f[1]->offset, f[1]->datatype)),
                       float(read_scalar(p + f[2]->offset, f[2]->datatype)));
    }
  }
  return out;
}

/// Splits like PCL's header reader (pcl::split): tokens between runs of tab, CR and space.
std::vector<std::string> split_pcd_line(const std::string& line) {
  std::vector<std::string> out;
  size_t b = line.find_first_not_of("\t\r ");
  while (b != std::string::npos) {
    const size_t e = std::min(line.find_first_of("\t\r ", b), line.size());
    out.push_back(line.substr(b, e - b));
    b = line.find_first_not_of("\t\r ", e);
  }
  return out;
}

/// PCL's PCD reader trusts its header: it allocates POINTS x point size (and a compressed
/// block's stated size) before looking at the data, maps binary data without checking the file's
/// length, writes each value with the size of its TYPE into a slot of the size of its SIZE, and
/// crashes on a header without fields (its debug line indexes fields[size() - 1]). Its header
/// loop also goes on after DATA, reading the lines that follow as header lines as long as they
/// start with a keyword, and ends at the first line that does not. So the header is read here
/// first, line for line as PCL reads it, and refused unless it is well-formed: each keyword at
/// most once; FIELDS, then SIZE (1, 2, 4 or 8 per field), TYPE (a valid type for that size),
/// COUNT (1 to 2^20) and POINTS in that order; decimal WIDTH/HEIGHT/POINTS below 2^31; a DATA line
/// with its encoding; and the data PCL will allocate within what the file holds (binary: the
/// points' bytes; ascii: 4 bytes per character, a value of at most 8 bytes taking at least a digit
/// and a separator; binary_compressed: its stated sizes, the compressed block in the file and at
/// most 100x expansion, LZF's limit being ~88x). The PCDs PCL and Open3D write pass.
void check_pcd_header(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(fmt::format("cannot open point cloud file '{}'", path));
  auto bad = [&](size_t line_no, const std::string& why) {
    return InputError(fmt::format("point cloud file '{}': PCD header line {}: {}", path, line_no, why));
  };
  auto number = [&](size_t line_no, const std::string& tok, uint64_t lo, uint64_t hi, const char* what) {
    if (tok.empty() || tok.size() > 12 || tok.find_first_not_of("0123456789") != std::string::npos)
      throw bad(line_no, fmt::format("{} '{}' is not a whole number", what, tok));
    const uint64_t v = std::stoull(tok);
    if (v < lo || v > hi) throw bad(line_no, fmt::format("{} {} is outside [{}, {}]", what, v, lo, hi));
    return v;
  };
  static const char* const kKeys[] = {"VERSION", "FIELDS", "SIZE", "TYPE", "COUNT",
                                      "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA"};
  enum Key { kVersion, kFields, kSize, kType, kCount, kWidth, kHeight, kViewpoint, kPoints, kData, kNumKeys };
  bool seen[kNumKeys] = {};
  size_t nfields = 0;
  std::vector<uint64_t> sizes, counts;
  uint64_t points = 0;
  int encoding = 0;  // as PCL: 0 ascii, 1 binary, 2 binary_compressed
  std::streamoff data_at = -1;
  std::string line;
  for (size_t line_no = 1; std::getline(f, line); ++line_no) {
    if (line.empty()) continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (!key.empty() && key[0] == '#') continue;
    int k = 0;
    while (k < kNumKeys && key.rfind(kKeys[k], 0) != 0) ++k;
    if (key.rfind("COLUMNS", 0) == 0) k = kFields;  // the old name of FIELDS
    if (k == kNumKeys || key.empty()) break;        // PCL's header ends here
    const std::vector<std::string> st = split_pcd_line(line);
    if (st.empty() || st[0] != key) throw bad(line_no, "unexpected whitespace characters");
    if (seen[k]) throw bad(line_no, fmt::format("{} appears twice", kKeys[k]));
    seen[k] = true;
    // After POINTS nothing may change the point size PCL allocated with there.
    if (seen[kPoints] && (k == kSize || k == kType || k == kCount))
      throw bad(line_no, fmt::format("{} after POINTS", kKeys[k]));
    const size_t n = st.size() - 1;
    auto need_before = [&](int earlier) {
      if (!seen[earlier]) throw bad(line_no, fmt::format("{} before {}", kKeys[k], kKeys[earlier]));
    };
    auto need_fields = [&] {
      if (n != nfields) throw bad(line_no, fmt::format("{} has {} values for {} fields", kKeys[k], n, nfields));
    };
    switch (k) {
      case kFields:
        if (n == 0) throw bad(line_no, "FIELDS names no field");
        nfields = n;
        sizes.assign(n, 4);
        counts.assign(n, 1);
        break;
      case kSize:
        need_before(kFields);
        need_fields();
        for (size_t i = 0; i < n; ++i) {
          sizes[i] = number(line_no, st[i + 1], 1, 8, "SIZE");
          if (sizes[i] != 1 && sizes[i] != 2 && sizes[i] != 4 && sizes[i] != 8)
            throw bad(line_no, fmt::format("SIZE {} is not 1, 2, 4 or 8", sizes[i]));
        }
        break;
      case kType:
        need_before(kSize);
        need_fields();
        for (size_t i = 0; i < n; ++i) {
          const std::string& t = st[i + 1];
          const char c = t.size() == 1 ? char(std::toupper(static_cast<unsigned char>(t[0]))) : '?';
          const bool ok = c == 'I' || c == 'U' || (c == 'F' && sizes[i] >= 4) || (c == 'B' && sizes[i] == 1);
          if (!ok) throw bad(line_no, fmt::format("TYPE '{}' does not fit SIZE {}", t, sizes[i]));
        }
        break;
      case kCount:
        need_before(kType);
        need_fields();
        for (size_t i = 0; i < n; ++i) counts[i] = number(line_no, st[i + 1], 1, uint64_t(1) << 20, "COUNT");
        break;
      case kWidth:
      case kHeight:
        if (n < 1) throw bad(line_no, fmt::format("{} has no value", kKeys[k]));
        number(line_no, st[1], 0, INT32_MAX, kKeys[k]);
        break;
      case kPoints:
        need_before(kFields);
        if (seen[kSize] && !seen[kType]) throw bad(line_no, "SIZE without TYPE");
        if (n < 1) throw bad(line_no, "POINTS has no value");
        points = number(line_no, st[1], 0, INT32_MAX, "POINTS");
        break;
      case kData:
        need_before(kFields);
        if (n < 1) throw bad(line_no, "DATA names no encoding (ascii, binary or binary_compressed)");
        encoding = st[1].rfind("binary_compressed", 0) == 0 ? 2 : st[1].rfind("binary", 0) == 0 ? 1 : 0;
        data_at = f.tellg();  // -1 when the file ends with this line
        if (data_at < 0) throw bad(line_no, "no data after the DATA line");
        break;
      default:  // VERSION, VIEWPOINT: nothing PCL allocates or indexes with
        break;
    }
  }
  if (!seen[kFields]) throw InputError(fmt::format("point cloud file '{}' has no PCD header (no FIELDS line)", path));
  if (data_at < 0) throw InputError(fmt::format("point cloud file '{}' has no PCD header (no DATA line)", path));
  if (seen[kSize] && !seen[kType])
    throw InputError(fmt::format("point cloud file '{}': its PCD header has SIZE without TYPE", path));
  uint64_t point_size = 0, data = 0;
  for (size_t i = 0; i < nfields; ++i) point_size += sizes[i] * counts[i];  // <= 2^23 per field
  if (__builtin_mul_overflow(points, point_size, &data)) data = UINT64_MAX;
  f.clear();
  f.seekg(0, std::ios::end);
  const uint64_t avail = uint64_t(f.tellg() - data_at);
  uint64_t limit = encoding == 1 ? avail : 4 * (avail + 1);
  const char* kind = encoding == 2 ? "binary_compressed" : encoding == 1 ? "binary" : "ascii";
  if (encoding == 2) {
    uint32_t sz[2] = {0, 0};  // compressed, uncompressed
    if (avail >= 8) {
      f.seekg(data_at);
      f.read(reinterpret_cast<char*>(sz), 8);
    }
    if (avail < 8 || avail - 8 < sz[0])
      throw InputError(fmt::format("point cloud file '{}' is truncated: {} bytes of {} data where the header needs {}",
                                   path, avail, kind, 8 + uint64_t(sz[0])));
    if (sz[1] != data)
      throw InputError(fmt::format("point cloud file '{}': its compressed block holds {} bytes, the header's points {}",
                                   path, sz[1], data));
    limit = 100 * uint64_t(sz[0]) + 100;
  }
  if (data > limit)
    throw InputError(fmt::format("point cloud file '{}' is truncated: {} bytes of {} data cannot hold the {} points "
                                 "({} bytes) of its header",
                                 path, avail, kind, points, data));
}

// --- PLY: the vertex element's x, y, z ------------------------------------------------------------
// Read here rather than with PCL's PLYReader, which allocates by the header's element counts
// before reading any data and aborts the process (a failed assert) on property layouts it does
// not expect, e.g. `green` and `blue` without `red` (found by tests/fuzz/fuzz_cloud_io).

struct PlyProperty {
  std::string name;
  int size = 0;        ///< bytes of the scalar, or of each list item
  char kind = 'f';     ///< 'i' signed, 'u' unsigned, 'f' floating point
  int count_size = 0;  ///< list properties: bytes of the item count (0: a scalar)
  char count_kind = 'u';
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> props;
};

/// Size and kind of a PLY scalar type name; false for an unknown name.
bool ply_type(const std::string& t, int* size, char* kind) {
  static const struct { const char* name; int size; char kind; } kTypes[] = {
      {"char", 1, 'i'},  {"int8", 1, 'i'},   {"uchar", 1, 'u'},  {"uint8", 1, 'u'},   {"short", 2, 'i'},
      {"int16", 2, 'i'}, {"ushort", 2, 'u'}, {"uint16", 2, 'u'}, {"int", 4, 'i'},     {"int32", 4, 'i'},
      {"uint", 4, 'u'},  {"uint32", 4, 'u'}, {"float", 4, 'f'},  {"float32", 4, 'f'}, {"double", 8, 'f'},
      {"float64", 8, 'f'}};
  for (const auto& e : kTypes)
    if (t == e.name) {
      *size = e.size;
      *kind = e.kind;
      return true;
    }
  return false;
}

/// A binary scalar at p (size bytes, byte order swapped when `swap`).
double ply_binary_value(const char* p, int size, char kind, bool swap) {
  unsigned char b[8];
  std::memcpy(b, p, size);
  if (swap) std::reverse(b, b + size);
  auto as = [&](auto v) {
    std::memcpy(&v, b, sizeof v);
    return double(v);
  };
  if (kind == 'f') return size == 4 ? as(float()) : as(double());
  if (kind == 'i') return size == 1 ? as(int8_t()) : size == 2 ? as(int16_t()) : as(int32_t());
  return size == 1 ? as(uint8_t()) : size == 2 ? as(uint16_t()) : as(uint32_t());
}

Cloud read_ply_vertices(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("cannot open point cloud file '{}'", path));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto bad = [&](const std::string& why) { return InputError(fmt::format("PLY file '{}': {}", path, why)); };

  // Header: "ply", "format ...", comments, elements with their properties, "end_header".
  std::vector<PlyElement> elements;
  std::string format;
  size_t pos = 0, line_no = 0;
  bool ended = false;
  while (!ended && pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::istringstream ls(text.substr(pos, end - pos));
    pos = end + 1;
    ++line_no;
    std::vector<std::string> t;
    for (std::string w; ls >> w;) t.push_back(w);
    if (line_no == 1) {
      if (t.size() != 1 || t[0] != "ply") throw bad("not a PLY file (the first line is not 'ply')");
      continue;
    }
    const std::string where = fmt::format("header line {}: ", line_no);
    if (t.empty() || t[0] == "comment" || t[0] == "obj_info") continue;
    if (t[0] == "end_header") {
      ended = true;
    } else if (t[0] == "format") {
      if (t.size() < 2 || (t[1] != "ascii" && t[1] != "binary_little_endian" && t[1] != "binary_big_endian"))
        throw bad(where + "format must be ascii, binary_little_endian or binary_big_endian");
      format = t[1];
    } else if (t[0] == "element") {
      if (t.size() != 3 || t[2].empty() || t[2].size() > 10 || t[2].find_first_not_of("0123456789") != std::string::npos ||
          std::stoull(t[2]) > uint64_t(INT32_MAX))
        throw bad(where + "an element line is 'element NAME COUNT' with COUNT below 2^31");
      elements.push_back({t[1], std::stoull(t[2]), {}});
    } else if (t[0] == "property") {
      if (elements.empty()) throw bad(where + "a property before any element");
      PlyProperty p;
      bool ok = false;
      if (t.size() == 3) {
        ok = ply_type(t[1], &p.size, &p.kind);
        p.name = t[2];
      } else if (t.size() == 5 && t[1] == "list") {
        ok = ply_type(t[2], &p.count_size, &p.count_kind) && p.count_kind != 'f' && ply_type(t[3], &p.size, &p.kind);
        p.name = t[4];
      }
      if (!ok) throw bad(where + "a property line is 'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME'");
      elements.back().props.push_back(p);
    } else {
      throw bad(where + fmt::format("unknown keyword '{}'", t[0]));
    }
  }
  if (!ended) throw bad("the header has no end_header line");
  pos = std::min(pos, text.size());  // the data start
  if (format.empty()) throw bad("the header has no format line");

  const auto vertex = std::find_if(elements.begin(), elements.end(), [](const PlyElement& e) { return e.name == "vertex"; });
  if (vertex == elements.end()) throw bad("no vertex element");
  int xyz[3] = {-1, -1, -1};
  const char* names[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    for (size_t i = 0; i < vertex->props.size(); ++i)
      if (vertex->props[i].name == names[k]) xyz[k] = int(i);
    if (xyz[k] < 0)
      throw InputError(fmt::format("point cloud '{}' has no '{}' field; expected fields x y z", path, names[k]));
    const PlyProperty& p = vertex->props[xyz[k]];
    if (p.count_size != 0 || p.kind != 'f')
      throw InputError(fmt::format("point cloud '{}': field '{}' is not float32 or float64", path, names[k]));
  }

  // Body: the elements in header order, up to and including the vertices.
  Cloud out;
  const bool ascii = format == "ascii";
  const bool swap = (format == "binary_big_endian") == (std::endian::native == std::endian::little);
  auto truncated = [&](const PlyElement& e, uint64_t i) {
    return bad(fmt::format("data ends in {} {} of {} (truncated file, or fewer values than the header declares)",
                           e.name, i, e.count));
  };
  // ascii: the next whitespace-separated token, empty at the end
  auto token = [&]() -> std::string_view {
    while (pos < text.size() && std::isspace(static_cast<unsigned char>(text[pos]))) ++pos;
    const size_t b = pos;
    while (pos < text.size() && !std::isspace(static_cast<unsigned char>(text[pos]))) ++pos;
    return std::string_view(text).substr(b, pos - b);
  };
  auto ascii_number = [&](std::string_view tok, double* v) {
    const std::string s(tok);
    char* stop = nullptr;
    *v = std::strtod(s.c_str(), &stop);
    return !s.empty() && stop == s.c_str() + s.size();
  };
  for (auto e = elements.begin(); e <= vertex; ++e) {
    if (e->props.empty()) continue;
    const bool is_vertex = e == vertex;
    if (is_vertex) out.reserve(std::min<uint64_t>(e->count, (text.size() - std::min(pos, text.size())) / 2 + 1));
    for (uint64_t i = 0; i < e->count; ++i) {
      double v[3] = {0, 0, 0};
      for (size_t j = 0; j < e->props.size(); ++j) {
        const PlyProperty& p = e->props[j];
        uint64_t items = 1;
        if (p.count_size != 0) {  // a list: its count, then that many items
          double n = 0;
          if (ascii) {
            const std::string_view tok = token();
            if (tok.empty()) throw truncated(*e, i);
            if (!ascii_number(tok, &n)) throw bad(fmt::format("{} {}: list count '{}' is not a number", e->name, i, tok));
          } else {
            if (text.size() - std::min(pos, text.size()) < size_t(p.count_size)) throw truncated(*e, i);
            n = ply_binary_value(text.data() + pos, p.count_size, p.count_kind, swap);
            pos += p.count_size;
          }
          if (!(n >= 0 && n <= double(text.size())) || n != std::floor(n))
            throw bad(fmt::format("{} {}: list count {} is not a count of the values that follow", e->name, i, n));
          items = uint64_t(n);
        }
        for (uint64_t q = 0; q < items; ++q) {
          double value = 0;
          if (ascii) {
            const std::string_view tok = token();
            if (tok.empty()) throw truncated(*e, i);
            if (!ascii_number(tok, &value))
              throw bad(fmt::format("{} {}: '{}' of property '{}' is not a number", e->name, i, tok, p.name));
          } else {
            if (text.size() - std::min(pos, text.size()) < size_t(p.size)) throw truncated(*e, i);
            if (is_vertex) value = ply_binary_value(text.data() + pos, p.size, p.kind, swap);
            pos += p.size;
          }
          if (is_vertex)
            for (int k = 0; k < 3; ++k)
              if (int(j) == xyz[k]) v[k] = value;
        }
      }
      if (is_vertex) out.emplace_back(float(v[0]), float(v[1]), float(v[2]));
    }
  }
  return out;
}

Cloud load_obj_vertices(const std::string& path) {
  const sim::Mesh m = sim::read_obj(path);
  if (m.x.empty()) throw InputError(fmt::format("OBJ file '{}' has no vertices (no 'v x y z' lines)", path));
  Cloud out;
  out.reserve(m.x.size());
  for (const sim::Vec3& v : m.x) out.push_back(v.cast<float>());
  return out;
}

pcl::PointCloud<pcl::PointXYZ> to_pcl_points(const Cloud& cloud) {
  pcl::PointCloud<pcl::PointXYZ> pc;
  pc.resize(cloud.size());
  bool dense = true;
  for (size_t i = 0; i < cloud.size(); ++i) {
    pc[i] = pcl::PointXYZ(cloud[i].x(), cloud[i].y(), cloud[i].z());
    dense = dense && cloud[i].allFinite();
  }
  pc.width = uint32_t(cloud.size());
  pc.height = 1;
  pc.is_dense = dense;
  return pc;
}

}  // namespace

Cloud load_cloud(const std::string& path) {
  namespace fs = std::filesystem;
  // PCL's PCD reader prints warnings for harmless things; keep errors only.
  static const bool quiet = [] {
    pcl::console::setVerbosityLevel(pcl::console::L_ERROR);
    return true;
  }();
  (void)quiet;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw InputError(fmt::format("point cloud file '{}' does not exist or is not a file", path));
  const std::string ext = lower_extension(path);
  Cloud raw;
  if (ext == ".obj") {
    raw = load_obj_vertices(path);
  } else if (ext == ".ply") {
    raw = read_ply_vertices(path);
  } else if (ext == ".pcd") {
    pcl::PCLPointCloud2 blob;
    int rc = -1;
    if (fs::file_size(path, ec) > 0) {
      check_pcd_header(path);
      pcl::PCDReader reader;
      rc = reader.read(path, blob);
    }
    if (rc < 0)
      throw InputError(fmt::format("cannot parse point cloud file '{}' (broken or unsupported {} "
                                   "file; PCL error code {})",
                                   path, ext, rc));
    raw = xyz_from_blob(blob, path);
  } else {
    throw InputError(fmt::format(
        "point cloud file '{}' has extension '{}'; expected .pcd, .ply or .obj", path, ext));
  }
  Cloud out;
  out.reserve(raw.size());
  for (const auto& p : raw)
    if (p.allFinite()) out.push_back(p);
  const size_t dropped = raw.size() - out.size();
  if (dropped > 0)
    gd::log().info("load_cloud: '{}': dropped {} non-finite of {} points", path, dropped,
                   raw.size());
  else
    gd::log().debug("load_cloud: '{}': {} points", path, out.size());
  return out;
}

void save_pcd(const std::string& path, const Cloud& cloud, PcdEncoding encoding) {
  const auto pc = to_pcl_points(cloud);
  pcl::PCDWriter writer;
  int rc = 0;
  if (cloud.empty()) {
    // PCL refuses to write empty clouds; write the header by hand.
    std::ofstream f(path);
    f << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
         "TYPE F F F\nCOUNT 1 1 1\nWIDTH 0\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 0\n"
         "DATA ascii\n";
    rc = f ? 0 : -1;
  } else {
    switch (encoding) {
      case PcdEncoding::kAscii: rc = writer.writeASCII(path, pc, 9); break;
      case PcdEncoding::kBinary: rc = writer.writeBinary(path, pc); break;
      case PcdEncoding::kBinaryCompressed: rc = writer.writeBinaryCompressed(path, pc); break;
    }
  }
  if (rc < 0) throw InputError(fmt::format("cannot write PCD file '{}'", path));
}

void save_pcd(const std::string& path, const Cloud& cloud, bool binary) {
  save_pcd(path, cloud, binary ? PcdEncoding::kBinary : PcdEncoding::kAscii);
}

void save_ply(const std::string& path, const Cloud& cloud, bool binary) {
  std::ofstream f(path, std::ios::binary);
  if (!f) throw InputError(fmt::format("cannot write PLY file '{}'", path));
  f << "ply\nformat " << (binary ? "binary_little_endian" : "ascii")
    << " 1.0\ncomment written by GarmentDynamics gd_metrics\nelement vertex " << cloud.size()
    << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  if (binary) {
    static_assert(std::endian::native == std::endian::little, "binary PLY writer assumes LE");
    for (const auto& p : cloud) f.write(reinterpret_cast<const char*>(p.data()), 3 * sizeof(float));
  } else {
    for (const auto& p : cloud) f << fmt::format("{} {} {}\n", p.x(), p.y(), p.z());
  }
  if (!f) throw InputError(fmt::format("error while writing PLY file '{}'", path));
}

Cloud transform_cloud(const Cloud& cloud, const Eigen::Matrix4d& T) {
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  Cloud out(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i)
    out[i] = (R * cloud[i].cast<double>() + t).cast<float>();
  return out;
}

}  // namespace gd::metrics
