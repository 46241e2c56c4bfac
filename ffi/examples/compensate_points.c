/* Loads a model once, then prints the joint command (rad, m; one line per target, values
 * separated by spaces) that puts its tool on each target point given on the command line as
 * x y z in metres, in the measurement (tracker) frame:
 *
 *     compensate_points MODEL x1 y1 z1 [x2 y2 z2 ...]
 *
 * Each command starts where `armcomp compensate` starts without --start (so the two give the
 * same commands); a controller passes its current joints instead. The calls after loading
 * allocate nothing. */
#include <stdio.h>
#include <stdlib.h>

#include "armcomp.h"

int main(int argc, char **argv) {
    if (argc < 5 || (argc - 2) % 3 != 0) {
        fprintf(stderr, "usage: %s MODEL x y z [x y z ...]  (m, measurement frame)\n", argv[0]);
        return 2;
    }
    char message[512];
    ArmcompModel *model = NULL;
    ArmcompStatus status = armcomp_model_load(argv[1], &model, message, sizeof message);
    if (status != ARMCOMP_STATUS_OK) {
        fprintf(stderr, "armcomp_model_load: %s\n", message);
        return 1;
    }
    size_t nq = armcomp_model_joint_count(model);
    /* Allocated once, before the loop a real-time thread would run. */
    double *q = calloc(nq, sizeof *q);
    if (q == NULL) {
        armcomp_model_free(model);
        return 1;
    }
    int code = 0;
    for (int i = 2; i + 2 < argc; i += 3) {
        double target[3] = {atof(argv[i]), atof(argv[i + 1]), atof(argv[i + 2])};
        status = armcomp_compensate(model, target, NULL, ARMCOMP_FRAME_MEASUREMENT,
                                    NULL, q, nq, message, sizeof message);
        if (status != ARMCOMP_STATUS_OK) {
            fprintf(stderr, "target %d: status %d: %s\n", (i - 2) / 3 + 1, (int)status, message);
            code = 1;
            break;
        }
        for (size_t k = 0; k < nq; k++) {
            printf(k == 0 ? "%.17g" : " %.17g", q[k]);
        }
        printf("\n");
    }
    free(q);
    armcomp_model_free(model);
    return code;
}
