#ifndef ARMCOMP_H
#define ARMCOMP_H

/* Generated from ffi/src/lib.rs by cbindgen; do not edit. */

#include <stddef.h>
#include <stdint.h>

/**
 * Targets are in the measurement (tracker) frame, as in measurement files and `armcomp
 * compensate --frame measurement`.
 */
#define ARMCOMP_FRAME_MEASUREMENT 0

/**
 * Targets are in the robot base frame.
 */
#define ARMCOMP_FRAME_BASE 1

/**
 * What a call did.
 */
typedef enum ArmcompStatus {
  /**
   * Success; the outputs are written.
   */
  ARMCOMP_STATUS_OK = 0,
  /**
   * A pointer that must not be null was null.
   */
  ARMCOMP_STATUS_NULL_ARGUMENT = 1,
  /**
   * An argument has the wrong value: a length, a frame, a non-finite number, a quaternion
   * that is not a unit one.
   */
  ARMCOMP_STATUS_INVALID_ARGUMENT = 2,
  /**
   * The model file could not be read or built (the message names the file and why).
   */
  ARMCOMP_STATUS_LOAD_FAILED = 3,
  /**
   * The inverse kinematics reached no command that puts the tool on the target; the
   * command is not written.
   */
  ARMCOMP_STATUS_UNREACHABLE = 4,
  /**
   * The command is written but the model with its predicted residual still misses the
   * target by more than the tolerance (the message says by how much).
   */
  ARMCOMP_STATUS_NOT_CONVERGED = 5,
  /**
   * An internal error (a bug); the handle should be freed.
   */
  ARMCOMP_STATUS_INTERNAL = 6,
} ArmcompStatus;

/**
 * A loaded model with the workspaces of its calls (opaque to C).
 */
typedef struct ArmcompModel ArmcompModel;

#ifdef __cplusplus
extern "C" {
#endif // __cplusplus

/**
 * Loads the model file at `path` (NUL-terminated, UTF-8): a robot or model file (TOML or
 * JSON) or a bare URDF. On success `*model` is a new handle (free it with
 * [`armcomp_model_free`]); otherwise `*model` is null and `message` says why. Run-time plugin
 * libraries are not loaded.
 *
 * # Safety
 * `path` is null or a NUL-terminated string; `model` is null or writable; `message` is null
 * or points to `message_len` writable bytes.
 */
enum ArmcompStatus armcomp_model_load(const char *path,
                                      struct ArmcompModel **model,
                                      char *message,
                                      size_t message_len);

/**
 * Frees a handle from [`armcomp_model_load`]; null is ignored.
 *
 * # Safety
 * `model` is null or a handle from [`armcomp_model_load`] not yet freed, used by no other
 * call now or later.
 */
void armcomp_model_free(struct ArmcompModel *model);

/**
 * The number of joint values a command has (the model's independent coordinates); 0 for a
 * null handle.
 *
 * # Safety
 * `model` is null or a live handle.
 */
size_t armcomp_model_joint_count(const struct ArmcompModel *model);

/**
 * The name of joint value `index` (NUL-terminated, owned by the handle and valid until it is
 * freed), in the order of commands; null for a null handle or an index out of range.
 *
 * # Safety
 * `model` is null or a live handle.
 */
const char *armcomp_model_joint_name(const struct ArmcompModel *model, size_t index);

/**
 * The joint command (SI: rad, m; [`armcomp_model_joint_count`] values into `q_out`) that
 * puts the model's tool on `position` (3 values, m) and, when `orientation_wxyz` is not null,
 * keeps the tool at that orientation (unit quaternion w, x, y, z). Both are in `frame`
 * ([`ARMCOMP_FRAME_MEASUREMENT`] or [`ARMCOMP_FRAME_BASE`]). It starts from `q_start` (the
 * controller's current joints, `q_len` values) or, when null, where `armcomp compensate`
 * starts without `--start`; joints that do not move the tool keep their start values.
 * Allocates nothing and takes no lock when it succeeds. On [`ArmcompStatus::NotConverged`]
 * the command is written and the message says how far it misses.
 *
 * # Safety
 * `model` is null or a live handle no other thread uses during the call; `position` is null
 * or points to 3 values, `orientation_wxyz` to 4 (or is null), `q_start` to `q_len` values
 * (or is null), `q_out` to `q_len` writable values (or is null); `message` is null or points
 * to `message_len` writable bytes.
 */
enum ArmcompStatus armcomp_compensate(struct ArmcompModel *model,
                                      const double *position,
                                      const double *orientation_wxyz,
                                      int32_t frame,
                                      const double *q_start,
                                      double *q_out,
                                      size_t q_len,
                                      char *message,
                                      size_t message_len);

#ifdef __cplusplus
}  // extern "C"
#endif  // __cplusplus

#endif  /* ARMCOMP_H */
