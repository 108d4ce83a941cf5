// The XDMF sidecar of an HDF5 export (docs/formats.md): the XML that lets
// ParaView and VisIt read the frames as a time series, the particles with
// every per-particle dataset as a point array, the walls (the same particles
// at every time) and the density field, when exported, as a uniform grid of
// its voxel centres (contour it at the dataset's iso for the surface).
#pragma once

#include <cstddef>
#include <ostream>
#include <string>
#include <vector>

namespace sphray {

// What the sidecar says of one written frame.
struct XdmfFrame {
  double time;
  size_t particles;
  bool velocity, density, pressure, presence, field;
  int field_dims[3];  // nx, ny, nz
  float field_origin[3], field_voxel;
};

// The group name of frame k under /frames ("000042").
std::string frame_name(size_t k);

// The document for the frames of the HDF5 file `h5_name` (as the sidecar,
// next to it, names it), whose walls hold `boundary` particles.
void write_xdmf_document(std::ostream& o, const std::string& h5_name, size_t boundary,
                         const std::vector<XdmfFrame>& frames);

}  // namespace sphray
