// Loads a model once and prints the joint command (rad, m, separated by spaces) that puts its
// tool at a pose in the robot base frame: position x y z in metres and orientation as a unit
// quaternion w x y z,
//
//     compensate_pose MODEL x y z qw qx qy qz
//
// The handle is owned by a std::unique_ptr; the buffers are sized once after loading.
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <vector>

#include "armcomp.h"

namespace {

struct ModelDeleter {
    void operator()(ArmcompModel *model) const { armcomp_model_free(model); }
};
using Model = std::unique_ptr<ArmcompModel, ModelDeleter>;

}  // namespace

int main(int argc, char **argv) {
    if (argc != 9) {
        std::fprintf(stderr, "usage: %s MODEL x y z qw qx qy qz  (m, base frame)\n", argv[0]);
        return 2;
    }
    char message[512];
    ArmcompModel *raw = nullptr;
    if (armcomp_model_load(argv[1], &raw, message, sizeof message) != ARMCOMP_STATUS_OK) {
        std::fprintf(stderr, "armcomp_model_load: %s\n", message);
        return 1;
    }
    Model model(raw);
    std::vector<double> q(armcomp_model_joint_count(model.get()));
    const double position[3] = {std::atof(argv[2]), std::atof(argv[3]), std::atof(argv[4])};
    const double orientation[4] = {std::atof(argv[5]), std::atof(argv[6]), std::atof(argv[7]),
                                   std::atof(argv[8])};
    ArmcompStatus status = armcomp_compensate(model.get(), position, orientation, ARMCOMP_FRAME_BASE,
                                              nullptr, q.data(), q.size(), message, sizeof message);
    if (status != ARMCOMP_STATUS_OK) {
        std::fprintf(stderr, "status %d: %s\n", static_cast<int>(status), message);
        return 1;
    }
    for (std::size_t k = 0; k < q.size(); k++) {
        std::printf(k == 0 ? "%.17g" : " %.17g", q[k]);
    }
    std::printf("\n");
    return 0;
}
