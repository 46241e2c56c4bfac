// C ABI over pinocchio's kinematics for `benches/vs_pinocchio.rs` (see README.md).
//
// A handle holds one pinocchio Model and its Data. The loop entry points run one algorithm over
// `n` configurations (row-major, `nq` values each) and write each configuration's result to
// `out + i * out_stride`: a stride of 0 overwrites one slot (timed runs, so the cost of the
// result's memory traffic stays out of the timings), the full width keeps every result (checks).
// Every entry point returns 0 on success or an error code; no C++ exception crosses the boundary
// and the message of the last error on the calling thread is `pinshim_last_error()`.

#include <cstddef>
#include <cstring>
#include <exception>
#include <string>
#include <utility>

#include <console_bridge/console.h>

#include "pinocchio/algorithm/frames.hpp"
#include "pinocchio/algorithm/jacobian.hpp"
#include "pinocchio/algorithm/kinematics.hpp"
#include "pinocchio/multibody.hpp"
#include "pinocchio/parsers/urdf.hpp"

namespace {

constexpr int PINSHIM_OK = 0;
constexpr int PINSHIM_EXCEPTION = 1;  // pinocchio or the standard library threw
constexpr int PINSHIM_NOT_FOUND = 2;  // no joint or frame of that name
constexpr int PINSHIM_ARGUMENT = 3;   // null pointer or index out of range

thread_local std::string last_error;

struct Handle {
  pinocchio::Model model;
  pinocchio::Data data;
  // The frame Jacobian the loops fill. pinocchio writes only the columns of the frame's support,
  // so it is zeroed when the frame changes, not per call (what a caller reusing it would do).
  pinocchio::Data::Matrix6x jacobian;
  std::size_t jacobian_frame = static_cast<std::size_t>(-1);

  pinocchio::Data::Matrix6x& jacobian_of(std::size_t frame) {
    if (frame != jacobian_frame) {
      jacobian.setZero();
      jacobian_frame = frame;
    }
    return jacobian;
  }
};

int fail(int code, std::string message) {
  last_error = std::move(message);
  return code;
}

// Runs `body`, turning any exception into an error code.
template <typename F>
int guarded(F&& body) {
  try {
    return body();
  } catch (const std::exception& e) {
    return fail(PINSHIM_EXCEPTION, e.what());
  } catch (...) {
    return fail(PINSHIM_EXCEPTION, "unknown C++ exception");
  }
}

using ConstQ = Eigen::Map<const Eigen::VectorXd>;

int check_loop(const Handle* h, std::size_t frame, const double* qs, const double* out) {
  if (h == nullptr || qs == nullptr || out == nullptr) return fail(PINSHIM_ARGUMENT, "null pointer");
  if (frame >= h->model.frames.size()) return fail(PINSHIM_ARGUMENT, "frame id out of range");
  return PINSHIM_OK;
}

// Column-major 6 x nv Jacobian into `out`.
void write_jacobian(const pinocchio::Data::Matrix6x& j, double* out) {
  std::memcpy(out, j.data(), sizeof(double) * static_cast<std::size_t>(j.size()));
}

// Position then column-major rotation (12 values).
void write_pose(const pinocchio::SE3& m, double* out) {
  Eigen::Map<Eigen::Vector3d> position(out);
  Eigen::Map<Eigen::Matrix3d> rotation(out + 3);
  position = m.translation();
  rotation = m.rotation();
}

}  // namespace

#define PINSHIM_API __attribute__((visibility("default")))

extern "C" {

PINSHIM_API const char* pinshim_last_error() { return last_error.c_str(); }

// Reads the URDF at `path` (fixed base; with `mimic` nonzero, <mimic> joints follow the joint
// they name instead of moving on their own) into a new handle.
PINSHIM_API int pinshim_load(const char* path, int mimic, Handle** handle) {
  return guarded([&] {
    if (path == nullptr || handle == nullptr) return fail(PINSHIM_ARGUMENT, "null pointer");
    // urdfdom's warnings (undefined visual materials in some published URDFs) would interleave
    // with the bench's table; errors still print.
    console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_ERROR);
    auto* h = new Handle();
    try {
      pinocchio::urdf::buildModel(std::string(path), h->model, false, mimic != 0);
      h->data = pinocchio::Data(h->model);
      h->jacobian = pinocchio::Data::Matrix6x::Zero(6, h->model.nv);
    } catch (...) {
      delete h;
      throw;
    }
    *handle = h;
    return PINSHIM_OK;
  });
}

PINSHIM_API void pinshim_free(Handle* handle) { delete handle; }

PINSHIM_API int pinshim_dims(const Handle* h, std::size_t* nq, std::size_t* nv, std::size_t* nframes) {
  return guarded([&] {
    if (h == nullptr || nq == nullptr || nv == nullptr || nframes == nullptr)
      return fail(PINSHIM_ARGUMENT, "null pointer");
    *nq = static_cast<std::size_t>(h->model.nq);
    *nv = static_cast<std::size_t>(h->model.nv);
    *nframes = h->model.frames.size();
    return PINSHIM_OK;
  });
}

// Where joint `name` sits in q and in the velocity (Jacobian columns): first index and width.
// A continuous joint takes two q values (cos, sin) and one velocity; a mimic joint none.
PINSHIM_API int pinshim_joint(const Handle* h, const char* name, std::size_t* idx_q, std::size_t* nq,
                              std::size_t* idx_v, std::size_t* nv) {
  return guarded([&] {
    if (h == nullptr || name == nullptr || idx_q == nullptr || nq == nullptr || idx_v == nullptr ||
        nv == nullptr)
      return fail(PINSHIM_ARGUMENT, "null pointer");
    if (!h->model.existJointName(name))
      return fail(PINSHIM_NOT_FOUND, std::string("no joint `") + name + "`");
    const auto& joint = h->model.joints[h->model.getJointId(name)];
    *idx_q = static_cast<std::size_t>(joint.idx_q());
    *nq = static_cast<std::size_t>(joint.nq());
    *idx_v = static_cast<std::size_t>(joint.idx_v());
    *nv = static_cast<std::size_t>(joint.nv());
    return PINSHIM_OK;
  });
}

// Id of the BODY frame of URDF link `name`.
PINSHIM_API int pinshim_frame_id(const Handle* h, const char* name, std::size_t* id) {
  return guarded([&] {
    if (h == nullptr || name == nullptr || id == nullptr) return fail(PINSHIM_ARGUMENT, "null pointer");
    if (!h->model.existFrame(name, pinocchio::BODY))
      return fail(PINSHIM_NOT_FOUND, std::string("no link frame `") + name + "`");
    *id = h->model.getFrameId(name, pinocchio::BODY);
    return PINSHIM_OK;
  });
}

// FK to one frame: forwardKinematics + updateFramePlacement; the frame's pose (12 values).
PINSHIM_API int pinshim_fk_frame(Handle* h, std::size_t frame, std::size_t n, const double* qs, double* out,
                                 std::size_t out_stride) {
  return guarded([&] {
    if (int e = check_loop(h, frame, qs, out)) return e;
    const auto nq = static_cast<std::size_t>(h->model.nq);
    for (std::size_t i = 0; i < n; ++i) {
      pinocchio::forwardKinematics(h->model, h->data, ConstQ(qs + i * nq, h->model.nq));
      write_pose(pinocchio::updateFramePlacement(h->model, h->data, frame), out + i * out_stride);
    }
    return PINSHIM_OK;
  });
}

// All frames: framesForwardKinematics; the positions of `nsel` frames `sel` (3 values each).
PINSHIM_API int pinshim_fk_all(Handle* h, const std::size_t* sel, std::size_t nsel, std::size_t n,
                               const double* qs, double* out, std::size_t out_stride) {
  return guarded([&] {
    if (sel == nullptr) return fail(PINSHIM_ARGUMENT, "null pointer");
    if (int e = check_loop(h, 0, qs, out)) return e;  // frame 0, the universe, always exists
    for (std::size_t k = 0; k < nsel; ++k)
      if (sel[k] >= h->model.frames.size()) return fail(PINSHIM_ARGUMENT, "frame id out of range");
    const auto nq = static_cast<std::size_t>(h->model.nq);
    for (std::size_t i = 0; i < n; ++i) {
      pinocchio::framesForwardKinematics(h->model, h->data, ConstQ(qs + i * nq, h->model.nq));
      double* o = out + i * out_stride;
      for (std::size_t k = 0; k < nsel; ++k) {
        Eigen::Map<Eigen::Vector3d> position(o + 3 * k);
        position = h->data.oMf[sel[k]].translation();
      }
    }
    return PINSHIM_OK;
  });
}

// 6 x nv Jacobian of `frame` from q: computeFrameJacobian, LOCAL_WORLD_ALIGNED (rows 0-2 the
// linear velocity of the frame's origin, 3-5 the angular velocity, world axes), column-major.
PINSHIM_API int pinshim_frame_jacobian(Handle* h, std::size_t frame, std::size_t n, const double* qs,
                                       double* out, std::size_t out_stride) {
  return guarded([&] {
    if (int e = check_loop(h, frame, qs, out)) return e;
    const auto nq = static_cast<std::size_t>(h->model.nq);
    auto& jacobian = h->jacobian_of(frame);
    for (std::size_t i = 0; i < n; ++i) {
      pinocchio::computeFrameJacobian(h->model, h->data, ConstQ(qs + i * nq, h->model.nq), frame,
                                      pinocchio::LOCAL_WORLD_ALIGNED, jacobian);
      write_jacobian(jacobian, out + i * out_stride);
    }
    return PINSHIM_OK;
  });
}

// What getFrameJacobian needs first: computeJointJacobians (FK and every joint's Jacobian
// column). Writes nothing; `pinshim_joint_jacobians_then_frame` minus this is the frame
// Jacobian alone.
PINSHIM_API int pinshim_joint_jacobians(Handle* h, std::size_t n, const double* qs) {
  return guarded([&] {
    if (h == nullptr || qs == nullptr) return fail(PINSHIM_ARGUMENT, "null pointer");
    const auto nq = static_cast<std::size_t>(h->model.nq);
    for (std::size_t i = 0; i < n; ++i)
      pinocchio::computeJointJacobians(h->model, h->data, ConstQ(qs + i * nq, h->model.nq));
    return PINSHIM_OK;
  });
}

// computeJointJacobians then getFrameJacobian of `frame` (LOCAL_WORLD_ALIGNED, as above).
PINSHIM_API int pinshim_joint_jacobians_then_frame(Handle* h, std::size_t frame, std::size_t n,
                                                   const double* qs, double* out, std::size_t out_stride) {
  return guarded([&] {
    if (int e = check_loop(h, frame, qs, out)) return e;
    const auto nq = static_cast<std::size_t>(h->model.nq);
    auto& jacobian = h->jacobian_of(frame);
    for (std::size_t i = 0; i < n; ++i) {
      pinocchio::computeJointJacobians(h->model, h->data, ConstQ(qs + i * nq, h->model.nq));
      pinocchio::getFrameJacobian(h->model, h->data, frame, pinocchio::LOCAL_WORLD_ALIGNED, jacobian);
      write_jacobian(jacobian, out + i * out_stride);
    }
    return PINSHIM_OK;
  });
}

}  // extern "C"
