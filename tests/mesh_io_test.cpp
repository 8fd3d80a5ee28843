// Mesh files written here by hand in every supported flavour (ASCII and binary STL, ASCII and
// binary little-endian PLY, OBJ with its index forms) read back to the same surface; damaged files
// are bad input naming the file.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "engine/error.hpp"
#include "engine/mesh_io.hpp"

namespace fluoro {
namespace {

namespace fs = std::filesystem;

class MeshIo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("fluoro_mesh_io_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& bytes) const {
    const std::string p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
  }
  template <class T>
  static void put(std::string& s, T v) {
    s.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  // The problem message of read_mesh on this file ("" when it reads).
  static std::string error_of(const std::string& path) {
    try {
      read_mesh(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

// A tetrahedron: 4 vertices, 4 triangles.
const Eigen::Vector3d kTet[4] = {{0, 0, 0}, {10.5, 0, 0}, {0, 20.25, 0}, {0, 0, -30.125}};
const int kFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

void expect_tetrahedron(const TriangleMesh& m) {
  ASSERT_EQ(m.triangles.size(), 4u);
  for (int t = 0; t < 4; ++t)
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(m.vertices[size_t(m.triangles[size_t(t)][size_t(k)])].isApprox(kTet[kFaces[t][k]]));
}

TEST_F(MeshIo, AsciiStl) {
  std::string s = "solid tet\n";
  for (const auto& f : kFaces) {
    s += "  facet normal 0 0 0\n    outer loop\n";
    for (int k : f) s += "      vertex " + std::to_string(kTet[k].x()) + " " + std::to_string(kTet[k].y()) + " " + std::to_string(kTet[k].z()) + "\n";
    s += "    endloop\n  endfacet\n";
  }
  s += "endsolid tet\n";
  expect_tetrahedron(read_mesh(write("tet.stl", s)));
}

TEST_F(MeshIo, BinaryStlEvenWhenItsHeaderSaysSolid) {
  std::string s = "solid but binary";
  s.resize(80, ' ');
  put<uint32_t>(s, 4);
  for (const auto& f : kFaces) {
    for (int i = 0; i < 3; ++i) put<float>(s, 0.f);
    for (int k : f)
      for (int i = 0; i < 3; ++i) put<float>(s, float(kTet[k][i]));
    put<uint16_t>(s, 0);
  }
  expect_tetrahedron(read_mesh(write("tet.STL", s)));
  // One byte short: neither a binary STL of 4 triangles nor valid ASCII.
  EXPECT_NE(error_of(write("cut.stl", s.substr(0, s.size() - 1))).find("cut.stl"), std::string::npos);
}

TEST_F(MeshIo, AsciiPlyWithQuadAndExtraProperties) {
  // A unit square as one quad plus a triangle, normals and an extra element to skip.
  const std::string s =
      "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 5\nproperty float x\nproperty float y\n"
      "property float z\nproperty float nx\nelement face 2\nproperty list uchar int vertex_indices\n"
      "property uchar red\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
      "0 0 0 1\n1 0 0 1\n1 1 0 1\n0 1 0 1\n0.5 0.5 2 1\n4 0 1 2 3 255\n3 0 1 4 7\n0 1\n";
  const TriangleMesh m = read_mesh(write("quad.ply", s));
  ASSERT_EQ(m.vertices.size(), 5u);
  ASSERT_EQ(m.triangles.size(), 3u);  // the quad's fan of two, and the triangle
  EXPECT_EQ(m.triangles[1], (std::array<int, 3>{0, 2, 3}));
  EXPECT_TRUE(m.vertices[4].isApprox(Eigen::Vector3d(0.5, 0.5, 2)));
}

TEST_F(MeshIo, PlyFaceListsOtherThanIndicesMayHoldFloats) {
  // Texture coordinates per face corner, a float list after the indices (common in scanner output).
  const std::string s =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 6 0.25 0.5 0.75 0.125 0.5 1.5\n";
  const TriangleMesh m = read_mesh(write("tex.ply", s));
  ASSERT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.triangles[0], (std::array<int, 3>{0, 1, 2}));
}

TEST_F(MeshIo, BinaryLittleEndianPly) {
  std::string s =
      "ply\r\nformat binary_little_endian 1.0\r\nelement vertex 4\r\nproperty double x\r\nproperty double y\r\n"
      "property double z\r\nproperty uchar quality\r\nelement face 4\r\nproperty list uchar uint vertex_index\r\nend_header\r\n";
  for (const auto& v : kTet) {
    for (int i = 0; i < 3; ++i) put<double>(s, v[i]);
    put<uint8_t>(s, 7);
  }
  for (const auto& f : kFaces) {
    put<uint8_t>(s, 3);
    for (int k : f) put<uint32_t>(s, uint32_t(k));
  }
  expect_tetrahedron(read_mesh(write("tet.ply", s)));
  EXPECT_NE(error_of(write("short.ply", s.substr(0, s.size() - 2))).find("truncated"), std::string::npos);
  std::string big = s;
  big.replace(big.find("binary_little_endian"), 20, "binary_big_endian");
  EXPECT_NE(error_of(write("big.ply", big)).find("not supported"), std::string::npos);
}

TEST_F(MeshIo, ObjWithSlashFormsAndRelativeIndices) {
  std::string s = "# tetrahedron\no tet\n";
  for (const auto& v : kTet) s += "v " + std::to_string(v.x()) + " " + std::to_string(v.y()) + " " + std::to_string(v.z()) + "\n";
  s += "vn 0 0 1\nvt 0 0\ng faces\n";
  s += "f 1/1/1 3/1/1 2/1/1\n";  // v/vt/vn
  s += "f 1//1 2//1 4//1\n";     // v//vn
  s += "f -4 -1 -2\n";           // relative: vertices 1, 4, 3
  s += "f 2/1 3/1 4/1\n";        // v/vt
  expect_tetrahedron(read_mesh(write("tet.obj", s)));
}

TEST_F(MeshIo, DamagedFilesAreBadInputNamingTheFile) {
  EXPECT_NE(error_of(write("bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n")).find("bad_index.obj: line 4"), std::string::npos);
  EXPECT_NE(error_of(write("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")).find("out of range"), std::string::npos);
  EXPECT_NE(error_of(write("nan.obj", "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")).find("not finite"), std::string::npos);
  EXPECT_NE(error_of(write("empty.obj", "v 0 0 0\n")).find("no triangles"), std::string::npos);
  EXPECT_NE(error_of(write("range.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                        "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                        "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"))
                .find("refers to vertex 3"),
            std::string::npos);
  EXPECT_NE(error_of(write("mesh.vtk", "x")).find("unknown mesh format"), std::string::npos);
  EXPECT_NE(error_of((dir_ / "missing.stl").string()).find("file not found"), std::string::npos);
  EXPECT_NE(error_of(write("text.stl", "hello world")).find("text.stl"), std::string::npos);
}

}  // namespace
}  // namespace fluoro
