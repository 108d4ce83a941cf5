// HDF5 frame export (io/frames_h5.cpp): exact round trip of every dataset and
// attribute, a run killed with SIGKILL mid-export still opens with its
// frames, and every kind of bad file gets a clear error.
#include <hdf5.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <sys/wait.h>
#include <unistd.h>

#include "catch.h"
#include "helpers.h"
#include "io/export.h"
#include "field/field.h"
#include "io/frames_h5.h"
#include "render/frame_sink.h"
#include "render/render.h"

using namespace sphray;

// This process's own directory (helpers.h), and its name.
const std::string tmp = sphray::test::tmp_dir();
const std::string tmp_name = std::filesystem::path(tmp).filename().string();

namespace {

Scene small_scene() {
  return parse_scene(R"({"tank": {"min": [0,0,0], "max": [0.2,0.1,0.15]},
    "fluid": [{"min": [0,0,0], "max": [0.06,0.1,0.1]}], "sph": {"spacing": 0.01},
    "field": {"refine": 1}, "run": {"end_time": 1}})", "export.json");
}

std::string error_of(const std::string& path) {
  try {
    FrameReader r(path);
  } catch (const FrameFileError& e) {
    return e.what();
  }
  return "";
}

using test::has;
using test::run_cli;

}  // namespace

TEST_CASE("export round trip: every dataset and attribute reads back exactly", "[export]") {
  const Scene s = small_scene();
  const SphParams prm = make_params(s);
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::AtUntil));
  auto field = make_cpu_field_builder(make_field_setup(resolve_scene(s)), FieldKind::Presence);
  const std::set<std::string> all = parse_export_fields("velocity,density,pressure,presence,field");
  FileHeader h;
  h.scene_json = s.json.dump();
  h.version = sphray_version();
  h.backend = "cpu";
  h.boundary = {1.5f, -2.0f, 3.25f, 0.0f, 1e-7f, 7.0f};
  const std::string path = tmp + "/sphray_roundtrip.h5";
  std::vector<Frame> written;
  {
    FrameWriter w(path, h, 4);  // with gzip: compression must be lossless
    for (int k = 0; k < 3; ++k) {
      if (k > 0) test::run_until(*solver, 0.002 * k);
      field->build(solver->view());
      written.push_back(frame_of(*solver, prm, all, field.get()));
      Frame copy = written.back();
      w.submit(std::move(copy));
    }
    w.finish();
    CHECK(w.frames_written() == 3);
  }
  CHECK(written[0].presence.empty());  // no step has computed presence at t = 0
  CHECK_FALSE(written[2].presence.empty());
  const FrameReader r(path);
  CHECK(r.format_version() == kFramesFormatVersion);
  CHECK(r.header().scene_json == h.scene_json);
  CHECK(r.header().version == h.version);
  CHECK(r.header().backend == "cpu");
  CHECK(r.header().boundary == h.boundary);
  REQUIRE(r.frames().size() == 3);
  for (size_t k = 0; k < 3; ++k) {
    const Frame& a = written[k];
    const Frame b = r.read(k);
    INFO("frame " << k);
    CHECK(r.frames()[k].name == (k == 0 ? "000000" : k == 1 ? "000001" : "000002"));
    CHECK(b.time == a.time);
    CHECK(b.dt == a.dt);
    CHECK(b.step == a.step);
    CHECK(b.id == a.id);
    CHECK(b.position == a.position);
    CHECK(b.velocity == a.velocity);
    CHECK(b.density == a.density);
    CHECK(b.pressure == a.pressure);
    CHECK(b.presence == a.presence);
    CHECK(b.field == a.field);
    for (int d = 0; d < 3; ++d) {
      CHECK(b.field_dims[d] == a.field_dims[d]);
      CHECK(b.field_origin[d] == a.field_origin[d]);
    }
    CHECK(b.field_voxel == a.field_voxel);
    CHECK(b.field_iso == a.field_iso);
  }
  // Particles in initial-index order, pressure from the Tait equation.
  for (size_t i = 1; i < written[2].id.size(); ++i) CHECK(written[2].id[i] > written[2].id[i - 1]);
  CHECK(written[2].pressure[0] == tait_pressure(prm, written[2].density[0]));
  // The XDMF sidecar names every frame's positions.
  const std::string xmf = test::slurp(tmp + "/sphray_roundtrip.xmf");
  CHECK(has(xmf, "sphray_roundtrip.h5:/frames/000002/position"));
  CHECK(has(xmf, "CollectionType=\"Temporal\""));
}

TEST_CASE("a run killed with SIGKILL mid-export leaves a file that opens with its frames; while it ran, the file "
          "was refused to another writer and explained to a reader", "[export]") {
  const std::string path = tmp + "/sphray_killed.h5";
  std::remove(path.c_str());
  std::filesystem::remove(tmp + "/sphray_killed.xmf");
  const std::string scene = test::source_path("scenes/dam_break.json"), csv_path = tmp + "/sphray_killed.csv";
  std::fflush(stdout);  // the child must not repeat what the parent has buffered
  const pid_t pid = fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    std::freopen("/dev/null", "w", stdout);
    execl(SPHRAY_EXE, SPHRAY_EXE, "run", scene.c_str(), "--backend", "cpu", "--quiet", "--set", "sph.spacing=0.04",
          "--set", "run.output_interval=0.005", "--set", "run.end_time=100", "--export", path.c_str(),
          "--export-fields", "velocity,density", "--metrics-csv", csv_path.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait until the sidecar lists four frames (each written and flushed), then kill.
  bool ready = false;
  for (int t = 0; t < 1200 && !ready; ++t) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ready = has(test::slurp(tmp + "/sphray_killed.xmf"), "/frames/000003/");
  }
  // While the run writes the file: another writer is refused without touching
  // it (HDF5's create truncated it before failing on the lock, and the run
  // then finished a corrupt file), and a reader is told what holds it.
  if (ready) {
    const auto size = std::filesystem::file_size(path);
    try {
      FrameWriter w(path, FileHeader{"{}", "test", "cpu", {}}, 0);
      FAIL("a second writer opened a file being written");
    } catch (const FrameFileError& e) {
      CHECK(std::string(e.what()) == path + ": in use by another process (a run still writing it, or a program "
                                            "reading it); not overwritten");
    }
    CHECK(std::filesystem::file_size(path) >= size);  // not emptied (the run may have added a frame)
    CHECK(has(error_of(path), path + ": locked by another process (a run still writing it?)"));
  }
  kill(pid, SIGKILL);
  int status = 0;
  waitpid(pid, &status, 0);
  REQUIRE(ready);
  CHECK(WIFSIGNALED(status));
  const FrameReader r(path);
  REQUIRE(r.frames().size() >= 4);
  for (size_t k = 0; k < r.frames().size(); ++k) {
    const Frame f = r.read(k);
    CHECK(f.count() == r.frames()[k].particles);
    CHECK(f.count() > 0);
    CHECK(f.velocity.size() == 3 * f.count());
  }
  // The metrics CSV is flushed per row: its rows up to the kill are there, whole
  // (buffered, the killed run's CSV held its header at most).
  std::ifstream csv(csv_path);
  std::string line;
  int rows = -1;  // the header
  while (std::getline(csv, line)) {
    CHECK(std::count(line.begin(), line.end(), ',') == 5);
    ++rows;
  }
  CHECK(rows >= 4);
}

TEST_CASE("bad frame files: missing, not HDF5, truncated, foreign HDF5", "[export]") {
  CHECK(has(error_of("/nonexistent/frames.h5"), "cannot open (missing or unreadable)"));

  std::ofstream(tmp + "/sphray_text.h5") << "this is not an HDF5 file\n";
  CHECK(has(error_of(tmp + "/sphray_text.h5"), "not an HDF5 file"));

  {  // a valid file cut in half
    FileHeader h;
    h.scene_json = "{}";
    h.boundary.assign(3000, 1.0f);
    FrameWriter w(tmp + "/sphray_full.h5", h, 0);
    Frame f;
    f.id.assign(2000, 1);
    f.position.assign(6000, 2.0f);
    w.submit(std::move(f));
    w.finish();
    std::ifstream in(tmp + "/sphray_full.h5", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(tmp + "/sphray_truncated.h5", std::ios::binary).write(bytes.data(), std::streamsize(bytes.size() / 2));
  }
  const std::string truncated = error_of(tmp + "/sphray_truncated.h5");
  INFO(truncated);
  CHECK(!truncated.empty());
  CHECK((has(truncated, "truncated") || has(truncated, "not an HDF5")));

  {  // an HDF5 file that is not sphray's
    const hid_t f = H5Fcreate((tmp + "/sphray_foreign.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    REQUIRE(f >= 0);
    const hid_t g = H5Gcreate2(f, "data", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Gclose(g);
    H5Fclose(f);
  }
  CHECK(has(error_of(tmp + "/sphray_foreign.h5"), "not a sphray frames file"));

  CHECK_THROWS_AS(parse_export_fields("velocity,colour"), std::runtime_error);
}

namespace {

// Replaces (or adds) a float dataset in an existing file, as another tool might.
void put_dataset(const std::string& path, const std::string& name, const std::vector<float>& v,
                 std::vector<hsize_t> dims) {
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  REQUIRE(f >= 0);
  if (H5Lexists(f, name.c_str(), H5P_DEFAULT) > 0) H5Ldelete(f, name.c_str(), H5P_DEFAULT);
  const hid_t s = H5Screate_simple(int(dims.size()), dims.data(), nullptr);
  const hid_t d = H5Dcreate2(f, name.c_str(), H5T_IEEE_F32LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  REQUIRE(d >= 0);
  REQUIRE(H5Dwrite(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0);
  H5Dclose(d);
  H5Sclose(s);
  H5Fclose(f);
}

// A small tmpfs mounted at `dir` for the full-disk cases, unmounted when the
// case ends (also when a check throws). Only root may mount one: elsewhere
// mounted() is false and the case warns and passes.
struct TinyFs {
  std::string dir;
  bool ok;
  TinyFs(const std::string& d, const char* size) : dir(d) {
    std::system(("mkdir -p " + dir).c_str());
    ok = std::system(("mount -t tmpfs -o size=" + std::string(size) + " tmpfs " + dir + " 2>/dev/null").c_str()) == 0;
    if (!ok) WARN("cannot mount a small tmpfs here (not root?): the full-disk case was not exercised");
  }
  ~TinyFs() {
    if (ok) std::system(("umount " + dir).c_str());
  }
  bool mounted() const { return ok; }
};

std::string read_error(const std::string& path) {
  try {
    FrameReader(path).read(0);
  } catch (const FrameFileError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("a frame whose datasets disagree with its particles, or has a non-finite position, is refused by name",
          "[export]") {
  const std::string path = tmp + "/sphray_damaged.h5";
  auto write_valid = [&] {
    FrameWriter w(path, FileHeader{"{}", "test", "cpu", {}}, 0);
    Frame f;
    f.id = {0, 1, 2, 3};
    f.position.assign(12, 0.5f);
    f.velocity.assign(12, 0.0f);
    f.density.assign(4, 1000.0f);
    w.submit(std::move(f));
    w.finish();
  };
  write_valid();
  CHECK(read_error(path).empty());  // as written, it reads

  put_dataset(path, "/frames/000000/velocity", std::vector<float>(9, 0.0f), {3, 3});  // 3 particles' worth
  CHECK(read_error(path) == path + ": /frames/000000/velocity: 9 values, expected 12 (4 particles x 3)");

  write_valid();
  put_dataset(path, "/frames/000000/presence", std::vector<float>(12, 1.0f), {4, 3});
  CHECK(has(read_error(path), "/frames/000000/presence: 12 values, expected 24 (4 particles x 6)"));

  write_valid();
  put_dataset(path, "/frames/000000/position", {0.5f, 0.5f, 0.5f, 0.5f, NAN, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f},
              {4, 3});
  CHECK(read_error(path) == path + ": /frames/000000/position: particle 1 has a non-finite y (nan)");

  write_valid();
  put_dataset(path, "/frames/000000/field", std::vector<float>(8, 1.0f), {8});  // a flat array, not nz x ny x nx
  CHECK(has(read_error(path), "/frames/000000/field: not a 3D grid"));
}

TEST_CASE("a frame of a run that lost particles keeps ascending ids with gaps, each row its particle", "[export]") {
  // convert() takes a particle's id as its row while every initial particle
  // is present, and the id's rank among those present once some have gone.
  const Scene s = parse_scene(R"({"tank": {"min": [0,0,0], "max": [0.2,0.1,0.1], "open_top": true},
    "fluid": [{"min": [0.12,0.04,0.02], "max": [0.16,0.06,0.04], "velocity": [0,0,20]},
              {"min": [0.02,0.02,0.0], "max": [0.08,0.08,0.04]}],
    "sph": {"spacing": 0.01}, "run": {"end_time": 0.03}})", "gaps.json");
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  const SphParams prm = make_params(s);
  const std::set<std::string> fields = parse_export_fields("velocity,density,pressure");
  const size_t start = solver->num_fluid();
  for (const double t : {0.0, 0.03}) {
    test::run_until(*solver, t);
    INFO("t = " << t << ": " << solver->num_fluid() << " of " << start << " particles");
    const Frame f = frame_of(*solver, prm, fields, nullptr);
    const HostParticles h = solver->download();
    REQUIRE(f.count() == h.id.size());
    std::map<uint32_t, size_t> at;  // id -> index in the solver's order
    for (size_t i = 0; i < h.id.size(); ++i) at[h.id[i]] = i;
    size_t row = 0;
    for (const auto& [id, i] : at) {  // ascending ids
      CHECK(f.id[row] == id);
      for (int d = 0; d < 3; ++d) {
        CHECK(f.position[3 * row + d] == (&h.pos[i].x)[d]);
        CHECK(f.velocity[3 * row + d] == (&h.vel[i].x)[d]);
      }
      CHECK(f.density[row] == h.density[i]);
      CHECK(f.pressure[row] == tait_pressure(prm, h.density[i]));
      ++row;
    }
    if (t > 0) {
      CHECK(solver->num_removed() > 0);  // the jet (the first ids) has left: the ids no longer start at 0
      CHECK(f.id.front() > 0);
    }
  }
}

TEST_CASE("the XDMF sidecar describes every exported dataset as the HDF5 file holds it", "[export]") {
  // ParaView reads the export through the sidecar: particles with their
  // point arrays, walls, and the density field as a grid of voxel centres.
  // Checked here against the HDF5 file itself (tools/check_xdmf_paraview.py
  // opens it in ParaView, docs/formats.md).
  const std::string dir = tmp + "/sphray_xdmf", h5 = dir + "/run.h5", xmf = dir + "/run.xmf";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const test::CliResult r = run_cli(
      "run " + test::source_path("scenes/dam_break.json") + " --backend cpu --quiet --set sph.spacing=0.05 "
      "--set run.end_time=0.02 --set run.output_interval=0.01 --set tank.min=[1,0,0] --set tank.max=[2.6,0.67,0.6] "
      "--set fluid.0.min=[1,0,0] --set fluid.0.max=[1.4,0.67,0.3] --export " + h5 +
      " --export-fields velocity,density,pressure,presence,field");
  INFO(r.output);
  REQUIRE(r.code == 0);
  const std::string text = test::slurp(xmf);
  INFO(text.substr(0, 2000));
  const FrameReader file(h5);
  REQUIRE(file.frames().size() == 3);

  // Every HDF reference names a dataset of the file, with its dimensions.
  const hid_t f = H5Fopen(h5.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(f >= 0);
  const std::regex ref(R"re(<DataItem Dimensions="([0-9 ]+)" NumberType="(\w+)" Precision="4" Format="HDF">([^<:]+):([^<]+)</DataItem>)re");
  std::map<std::string, int> per_name;
  for (auto m = std::sregex_iterator(text.begin(), text.end(), ref); m != std::sregex_iterator(); ++m) {
    const std::string dims = (*m)[1], file_name = (*m)[3], path = (*m)[4];
    INFO(path);
    CHECK(file_name == "run.h5");  // relative: the two files move together
    REQUIRE(H5Lexists(f, path.c_str(), H5P_DEFAULT) > 0);
    const hid_t d = H5Dopen2(f, path.c_str(), H5P_DEFAULT), space = H5Dget_space(d);
    hsize_t shape[3] = {0, 0, 0};
    const int rank = H5Sget_simple_extent_dims(space, shape, nullptr);
    std::string held;
    for (int k = 0; k < rank; ++k) held += (k ? " " : "") + std::to_string(shape[k]);
    CHECK(dims == held);
    const std::string leaf = path.substr(path.rfind('/') + 1);
    CHECK((*m)[2] == (leaf == "id" ? "UInt" : "Float"));
    H5Sclose(space);
    H5Dclose(d);
    ++per_name[leaf];
  }
  H5Fclose(f);
  CHECK(per_name["position"] == 3 + 3);  // the particles' and the walls' of every frame
  CHECK(per_name["id"] == 3);
  CHECK(per_name["velocity"] == 3);
  CHECK(per_name["density"] == 3);
  CHECK(per_name["pressure"] == 3);
  CHECK(per_name["presence"] == 2);  // not at t = 0
  CHECK(per_name["field"] == 3);
  CHECK(has(text, R"(<Attribute Name="presence" AttributeType="Matrix" Center="Node">)"));
  CHECK(has(text, R"(<Attribute Name="velocity" AttributeType="Vector" Center="Node">)"));

  // The field's grid: axes slowest first (z y x), its points the voxel centres.
  const Frame fr = file.read(2);
  const std::regex geometry(R"re(ORIGIN_DXDYDZ">\s*<DataItem[^>]*>([^<]+)</DataItem>\s*<DataItem[^>]*>([^<]+)</DataItem>)re");
  std::smatch g;
  REQUIRE(std::regex_search(text, g, geometry));
  std::istringstream origin(g[1].str()), spacing(g[2].str());
  double o[3], v[3];
  origin >> o[0] >> o[1] >> o[2];
  spacing >> v[0] >> v[1] >> v[2];
  for (int k = 0; k < 3; ++k) {
    CHECK(o[k] == Approx(fr.field_origin[2 - k] + 0.5 * fr.field_voxel).margin(1e-6));
    CHECK(v[k] == Approx(fr.field_voxel));
  }
  CHECK(o[2] > 0.9);  // x: the tank starts at 1 m
  CHECK(has(text, "TopologyType=\"3DCoRectMesh\" Dimensions=\"" + std::to_string(fr.field_dims[2]) + " " +
                      std::to_string(fr.field_dims[1]) + " " + std::to_string(fr.field_dims[0]) + "\""));

  // Well-formed XML, where a parser is at hand.
  if (std::system("python3 -c 'import xml.etree.ElementTree' > /dev/null 2>&1") == 0)
    CHECK(std::system(("python3 -c 'import xml.etree.ElementTree as E; E.parse(\"" + xmf + "\")'").c_str()) == 0);
  else
    WARN("python3 not found: the sidecar's XML was not parsed");

  // Frames after every particle left through an open top: empty grids, and
  // `inspect` prints no ranges for them (it printed x [0, 0]).
  std::ofstream(dir + "/jet.json") << R"({"tank": {"min": [0,0,0], "max": [0.1,0.1,0.1], "open_top": true},
    "fluid": [{"min": [0.04,0.04,0.02], "max": [0.06,0.06,0.04], "velocity": [0,0,20]}],
    "sph": {"spacing": 0.01}, "run": {"end_time": 0.03, "output_interval": 0.01}})";
  REQUIRE(run_cli("run " + dir + "/jet.json --backend cpu --quiet --export " + dir + "/jet.h5").code == 0);
  const std::string jet = test::slurp(dir + "/jet.xmf");
  CHECK(has(jet, "<Topology TopologyType=\"Polyvertex\" NumberOfElements=\"0\"/>"));
  CHECK(has(jet, "<DataItem Dimensions=\"0 3\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">jet.h5:/frames/000003/position"));
  const test::CliResult ins = run_cli("inspect " + dir + "/jet.h5");
  INFO(ins.output);
  CHECK(has(ins.output, "000003  t = 0.03 s  step "));
  CHECK(has(ins.output, " 0 particles\n"));
  CHECK_FALSE(has(ins.output, "[0, 0]"));
}

TEST_CASE("large frames read back exactly, chunks written directly or through the deflate filter", "[export]") {
  // Uncompressed datasets go to the file chunk by chunk (H5Dwrite_chunk), the
  // last chunk padded: sizes that leave partial chunks in every dataset.
  const size_t n = 100003;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  Frame f;
  f.time = 0.25;
  f.step = 77;
  for (size_t i = 0; i < n; ++i) f.id.push_back(uint32_t(3 * i + 1));
  auto fill = [&](std::vector<float>& v, size_t count) {
    v.resize(count);
    for (float& x : v) x = u(rng);
  };
  fill(f.position, 3 * n);  // 87,381 rows a chunk: 2 chunks
  fill(f.velocity, 3 * n);
  fill(f.density, n);
  fill(f.pressure, n);
  fill(f.presence, 6 * n);  // 3 chunks
  f.field_dims[0] = 70, f.field_dims[1] = 60, f.field_dims[2] = 200;  // 62 z slices a chunk: 4 chunks
  fill(f.field, 70 * 60 * 200);
  f.field_voxel = 0.01f;
  for (const int gzip : {0, 3}) {
    INFO("gzip " << gzip);
    const std::string path = tmp + "/sphray_big_" + std::to_string(gzip) + ".h5";
    {
      FrameWriter w(path, FileHeader{"{}", "test", "cpu", {}}, gzip);
      Frame copy = f;
      w.submit(std::move(copy));
      w.finish();
    }
    const Frame b = FrameReader(path).read(0);
    CHECK(b.id == f.id);
    CHECK(b.position == f.position);
    CHECK(b.velocity == f.velocity);
    CHECK(b.density == f.density);
    CHECK(b.pressure == f.pressure);
    CHECK(b.presence == f.presence);
    CHECK(b.field == f.field);
    CHECK(b.time == f.time);
    CHECK(b.step == f.step);
  }
}

TEST_CASE("the XDMF sidecar is rewritten ever less often as it grows, and is complete at the end", "[export]") {
  // Rewritten after every frame, the sidecars of a run summed to the square
  // of its frames: 2,501 small frames took 47.6 s instead of 2.7 s.
  const std::string path = tmp + "/sphray_sidecar.h5";
  FrameWriter w(path, FileHeader{"{}", "test", "cpu", {0.5f, 0.5f, 0.5f}}, 0);
  for (int k = 0; k < 400; ++k) {
    Frame f;
    f.time = 0.001 * k;
    f.id = {0, 1};
    f.position.assign(6, 0.25f);
    w.submit(std::move(f));
  }
  w.finish();
  INFO(w.sidecar_writes() << " sidecar writes");
  // 16 while short, then each 1/16 more frames: about 16 per doubling of
  // the frames (16 + 16 log2(400 / 16) = 90 at most), one at the end, and at
  // most one more per second of the writer's time.
  CHECK(w.sidecar_writes() >= 60);
  CHECK(w.sidecar_writes() < 110);
  const std::string xmf = test::slurp(tmp + "/sphray_sidecar.xmf");
  CHECK(has(xmf, "sphray_sidecar.h5:/frames/000399/position"));
  CHECK(has(xmf, "<Grid Name=\"walls 399\""));
}

TEST_CASE("render --from refuses a particle outside the scene's domain, naming it", "[export]") {
  // The grid's key and the field's splat convert a position to integer cells;
  // one far outside (1e30) rendered silently, through a float -> int
  // conversion out of range. A run never writes one: another tank, or an edit.
  const std::string path = tmp + "/sphray_outside.h5";
  std::filesystem::remove(path);
  const std::string scene = test::source_path("scenes/stress/one_cell.json");  // tank 0 .. 0.1 m
  test::CliResult r = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.01 "
                              "--set run.output_interval=0.01 --export " + path);
  REQUIRE(r.code == 0);
  const std::string render = "render --from " + path + " --frame 1 --backend cpu --size 64x36 --out " + tmp + "/sphray_o.png";
  r = run_cli(render);
  CHECK(r.code == 0);  // as written, it renders

  std::vector<float> pos(FrameReader(path).read(1).position);
  REQUIRE(pos.size() == 24);
  pos[3 * 5 + 2] = 1e30f;
  put_dataset(path, "/frames/000001/position", pos, {8, 3});
  r = run_cli(render);
  INFO(r.output);
  CHECK(r.code == 2);
  CHECK(has(r.output, "frame 1, particle 5 at ("));
  CHECK(has(r.output, "1e+30) m is outside the scene's domain"));

  // The file as written, with the tank shrunk below its particles.
  r = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.01 --set run.output_interval=0.01 "
              "--export " + path);
  REQUIRE(r.code == 0);
  r = run_cli(render + " --set tank.min=[0.2,0,0] --set tank.max=[0.3,0.1,0.1] --set fluid=[]");
  INFO(r.output);
  CHECK(r.code == 2);
  CHECK(has(r.output, "is outside the scene's domain, x 0.14 .. "));
}

TEST_CASE("a full disk stops the run with a message and keeps the frames written before", "[export]") {
  const TinyFs fs(tmp + "/sphray_tiny_fs", "2m");
  if (!fs.mounted()) return;
  const auto [code, out] = run_cli("run " + test::source_path("scenes/stress/one_cell.json") +
                                      " --backend cpu --quiet --set run.end_time=0.2 --set run.output_interval=0.001"
                                      " --export " + fs.dir + "/x.h5 --export-fields velocity,density,field");
  INFO(out);
  CHECK(code == 1);
  CHECK(has(out, "not enough free space for frame"));
  const FrameReader r(fs.dir + "/x.h5");
  CHECK(r.frames().size() > 10);
  for (size_t k = 0; k < r.frames().size(); ++k) CHECK(r.read(k).count() == 8);
}

TEST_CASE("PNG frames on a full disk: the run stops naming the frame, and every PNG left is whole", "[export]") {
  // stb's own file writer ignored write errors: on a full disk the run
  // reported "11 PNGs" and left empty and truncated frames.
  const TinyFs fs(tmp + "/sphray_tiny_png", "200k");
  if (!fs.mounted()) return;
  const auto [code, out] = run_cli("run " + test::source_path("scenes/dam_break.json") +
                                      " --backend cpu --quiet --set sph.spacing=0.05 --set run.end_time=0.2"
                                      " --frames-dir " + fs.dir);
  INFO(out);
  CHECK(code == 1);  // a failed write during the run, as for the export
  CHECK(has(out, "--frames-dir: cannot write PNG '" + fs.dir + "/frame_"));
  CHECK(has(out, "No space left on device"));
  int whole = 0;
  for (const auto& e : std::filesystem::directory_iterator(fs.dir)) {
    const std::string name = e.path().filename().string();
    INFO(name);
    CHECK(e.path().extension() == ".png");  // no .tmp left behind
    const Image img = read_png(e.path().string());  // throws on a truncated file
    CHECK(img.width == 640);
    ++whole;
  }
  CHECK(whole >= 1);
}

TEST_CASE("metrics CSV and summary JSON on a full disk stop the run with the file named", "[export]") {
  // Unchecked, the CSV ended mid-run at 4 KiB and the summary was empty, exit 0.
  const TinyFs fs(tmp + "/sphray_tiny_csv", "8k");
  if (!fs.mounted()) return;
  const std::string run = "run " + test::source_path("scenes/dam_break.json") +
                          " --backend cpu --quiet --set sph.spacing=0.05 --set run.output_interval=0.001";
  const auto [code, out] = run_cli(run + " --set run.end_time=0.5 --metrics-csv " + fs.dir + "/m.csv");
  INFO(out);
  CHECK(code == 1);
  CHECK(has(out, "--metrics-csv: cannot write '" + fs.dir + "/m.csv': No space left on device"));
  std::filesystem::remove(fs.dir + "/m.csv");
  std::ofstream(fs.dir + "/fill") << std::string(7 * 1024, 'x');  // room for less than the summary
  const test::CliResult summary = run_cli(run + " --set run.end_time=0.01 --summary-json " + fs.dir + "/s.json");
  CHECK(summary.code == 1);
  CHECK(has(summary.output, "--summary-json: cannot write '" + fs.dir + "/s.json': No space left on device"));
}

TEST_CASE("the background queue runs jobs in order and stops at the first failure", "[export]") {
  std::vector<int> ran;
  BackgroundQueue q;
  for (int k = 0; k < 5; ++k) CHECK(q.submit([&ran, k] { ran.push_back(k); }));
  CHECK(q.finish());
  CHECK(ran == std::vector<int>{0, 1, 2, 3, 4});
  CHECK(q.done() == 5);

  std::vector<int> ran2;
  BackgroundQueue bad;
  CHECK(bad.submit([&] { ran2.push_back(0); }));
  CHECK(bad.submit([] { throw std::runtime_error("disk on fire"); }));
  // the failure is seen by a later submit (dropped) or by finish
  bool refused = false;
  for (int k = 1; k < 50 && !refused; ++k) {
    refused = !bad.submit([&ran2, k] { ran2.push_back(k); });
    if (!refused) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  CHECK_FALSE(bad.finish());
  CHECK(bad.failed());
  CHECK(bad.error() == "disk on fire");
  CHECK(bad.done() == ran2.size());
  CHECK(ran2.front() == 0);
}

TEST_CASE("PNG frames are written in the background; a failed write is reported by name", "[export]") {
  const Scene s = small_scene();
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  auto field = make_cpu_field_builder(make_field_setup(resolve_scene(s)), FieldKind::Naive);
  const std::string dir = tmp + "/sphray_bg_frames";
  std::filesystem::remove_all(dir);
  {
    FrameRenderer fr(s.render, s.tank, s.sph.spacing, Backend::Cpu, field->setup(), dir);
    field->build(solver->view());
    for (int f = 0; f < 3; ++f) fr.write_frame(solver->view(), field.get(), f);
    fr.finish();
    CHECK(fr.frames_written() == 3);
    for (int f = 0; f < 3; ++f) CHECK(std::filesystem::exists(dir + "/frame_00000" + std::to_string(f) + ".png"));
  }
  FrameRenderer fr(s.render, s.tank, s.sph.spacing, Backend::Cpu, field->setup(), dir);
  std::filesystem::remove_all(dir);  // the directory goes away under the run
  std::string msg;
  try {
    for (int f = 0; f < 20; ++f) fr.write_frame(solver->view(), field.get(), f);
    fr.finish();
  } catch (const std::runtime_error& e) {
    msg = e.what();
  }
  CHECK(msg.find("cannot write PNG '" + tmp + "/sphray_bg_frames/frame_000000.png'") != std::string::npos);
}

namespace {
int g_made_a = 0, g_freed_a = 0, g_freed_b = 0;
}  // namespace

TEST_CASE("pinned host blocks go back to the provider that made them, and fall back to malloc", "[export]") {
  // The CUDA backend installs cudaMallocHost when a device is used; snapshots
  // made before (or after a failed page-lock) must still be freed rightly.
  const HostMemoryProvider before = pinned_provider();
  set_pinned_provider({[](size_t b) -> void* { ++g_made_a; return std::malloc(b); },
                       [](void* p) { ++g_freed_a; std::free(p); }});
  auto* a = new PinnedVector<Float4>(1000, Float4{1, 2, 3, 4});
  CHECK(g_made_a == 1);
  CHECK(reinterpret_cast<uintptr_t>(a->data()) % alignof(Float4) == 0);
  set_pinned_provider({[](size_t) -> void* { return nullptr; },  // cannot page-lock: malloc's block
                       [](void* p) { ++g_freed_b; std::free(p); }});
  auto* b = new PinnedVector<uint32_t>(5000, 7u);
  CHECK((*b)[4999] == 7u);
  delete a;  // to the first provider
  CHECK(g_freed_a == 1);
  delete b;  // to malloc, not to the second provider
  CHECK(g_freed_b == 0);
  CHECK(g_freed_a == 1);
  set_pinned_provider(before);
}
