#include "xdmf.h"

#include <cstdio>

namespace sphray {

std::string frame_name(size_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06zu", k);
  return buf;
}

namespace {

// The XML pieces, naming datasets of one HDF5 file.
struct XdmfWriter {
  std::ostream& o;
  const std::string& h5;

  void item(const std::string& dims, const char* type, const std::string& path) {
    o << "<DataItem Dimensions=\"" << dims << "\" NumberType=\"" << type << "\" Precision=\"4\" Format=\"HDF\">" << h5
      << ":" << path << "</DataItem>";
  }
  void attribute(const char* name, const char* kind, const std::string& dims, const std::string& path,
                 const char* type = "Float") {
    o << "    <Attribute Name=\"" << name << "\" AttributeType=\"" << kind << "\" Center=\"Node\">\n     ";
    item(dims, type, path);
    o << "\n    </Attribute>\n";
  }

  // The walls at every frame's time, all from the one dataset: ParaView's
  // Xdmf3 readers drop a grid without a time from a file with time steps.
  void walls(size_t boundary, const std::vector<XdmfFrame>& frames) {
    const std::string b = std::to_string(boundary);
    o << "  <Grid Name=\"walls\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (size_t k = 0; k < frames.size(); ++k) {
      o << "   <Grid Name=\"walls " << k << "\" GridType=\"Uniform\">\n"
        << "    <Time Value=\"" << frames[k].time << "\"/>\n"
        << "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << b << "\"/>\n"
        << "    <Geometry GeometryType=\"XYZ\">\n     ";
      item(b + " 3", "Float", "/boundary/position");
      o << "\n    </Geometry>\n   </Grid>\n";
    }
    o << "  </Grid>\n";
  }

  void particles(const std::vector<XdmfFrame>& frames) {
    o << "  <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (size_t k = 0; k < frames.size(); ++k) {
      const XdmfFrame& x = frames[k];
      const std::string g = "/frames/" + frame_name(k), n = std::to_string(x.particles);
      o << "   <Grid Name=\"frame " << k << "\" GridType=\"Uniform\">\n"
        << "    <Time Value=\"" << x.time << "\"/>\n"
        << "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n << "\"/>\n"
        << "    <Geometry GeometryType=\"XYZ\">\n     ";
      item(n + " 3", "Float", g + "/position");
      o << "\n    </Geometry>\n";
      attribute("id", "Scalar", n, g + "/id", "UInt");
      if (x.velocity) attribute("velocity", "Vector", n + " 3", g + "/velocity");
      if (x.density) attribute("density", "Scalar", n, g + "/density");
      if (x.pressure) attribute("pressure", "Scalar", n, g + "/pressure");
      // six components, +x -x +y -y +z -z (ParaView's reader skips a HyperSlab per column)
      if (x.presence) attribute("presence", "Matrix", n + " 6", g + "/presence");
      o << "   </Grid>\n";
    }
    o << "  </Grid>\n";
  }

  void field(const std::vector<XdmfFrame>& frames) {
    o << "  <Grid Name=\"field\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (size_t k = 0; k < frames.size(); ++k) {
      const XdmfFrame& x = frames[k];
      if (!x.field) continue;
      // XDMF orders a structured grid's axes slowest first: z, y, x, as the dataset is stored.
      const std::string dims = std::to_string(x.field_dims[2]) + " " + std::to_string(x.field_dims[1]) + " " +
                               std::to_string(x.field_dims[0]);
      const float v = x.field_voxel;  // values sit at voxel centres, half a voxel in from `origin`
      o << "   <Grid Name=\"field " << k << "\" GridType=\"Uniform\">\n"
        << "    <Time Value=\"" << x.time << "\"/>\n"
        << "    <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"" << dims << "\"/>\n"
        << "    <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n"
        << "     <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"4\" Format=\"XML\">"
        << x.field_origin[2] + 0.5f * v << " " << x.field_origin[1] + 0.5f * v << " " << x.field_origin[0] + 0.5f * v
        << "</DataItem>\n"
        << "     <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"4\" Format=\"XML\">" << v << " " << v
        << " " << v << "</DataItem>\n    </Geometry>\n";
      attribute("field", "Scalar", dims, "/frames/" + frame_name(k) + "/field");
      o << "   </Grid>\n";
    }
    o << "  </Grid>\n";
  }
};

}  // namespace

void write_xdmf_document(std::ostream& o, const std::string& h5_name, size_t boundary,
                         const std::vector<XdmfFrame>& frames) {
  o.precision(10);
  XdmfWriter w{o, h5_name};
  o << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n";
  if (boundary > 0) w.walls(boundary, frames);
  w.particles(frames);
  bool any_field = false;
  for (const XdmfFrame& x : frames) any_field = any_field || x.field;
  if (any_field) w.field(frames);
  o << " </Domain>\n</Xdmf>\n";
}

}  // namespace sphray
