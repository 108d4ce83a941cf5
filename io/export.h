// From the simulation to an HDF5 frame (frames_h5.h): which fields a run
// exports, and one frame of a solver's state in initial-index order.
#pragma once

#include <functional>
#include <memory>
#include <set>
#include <string>

#include "field/field.h"
#include "frames_h5.h"
#include "sph/solver.h"

namespace sphray {

// "a,b,c" from --export-fields; throws std::runtime_error naming an unknown field.
std::set<std::string> parse_export_fields(const std::string& text);

// What a frame needs, copied from the solver (and the field) as it is; the
// returned function makes the frame (ordering, conversions) and is meant to
// run on the writer's thread (FrameWriter::submit). Its buffers are reused by
// a later capture once the frame is released.
std::function<std::shared_ptr<const Frame>()> capture_frame(const Solver& s, const SphParams& prm,
                                                            const std::set<std::string>& fields,
                                                            const FieldBuilder* field);

// The fluid sorted by initial index, with the fields asked for (presence only
// when the solver's last step computed it; the field from `field`'s last build).
Frame frame_of(const Solver& s, const SphParams& prm, const std::set<std::string>& fields, const FieldBuilder* field);

}  // namespace sphray
