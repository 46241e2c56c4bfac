/* Latency per armcomp_compensate call: loads a model, then times ROUNDS passes (default 200)
 * over 27 point targets on a 4 cm grid centred on x y z (m, measurement frame), each call from
 * the default start, and prints the median, 99th percentile and largest time per call in
 * microseconds:
 *
 *     latency MODEL x y z [ROUNDS]
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "armcomp.h"

static int compare(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s MODEL x y z [ROUNDS]  (m, measurement frame)\n", argv[0]);
        return 2;
    }
    int rounds = argc > 5 ? atoi(argv[5]) : 200;
    char message[512];
    ArmcompModel *model = NULL;
    if (armcomp_model_load(argv[1], &model, message, sizeof message) != ARMCOMP_STATUS_OK) {
        fprintf(stderr, "armcomp_model_load: %s\n", message);
        return 1;
    }
    size_t nq = armcomp_model_joint_count(model);
    enum { TARGETS = 27 };
    double targets[TARGETS][3];
    for (int i = 0; i < TARGETS; i++) {
        targets[i][0] = atof(argv[2]) + 0.02 * (i % 3 - 1);
        targets[i][1] = atof(argv[3]) + 0.02 * (i / 3 % 3 - 1);
        targets[i][2] = atof(argv[4]) + 0.02 * (i / 9 - 1);
    }
    double *q = calloc(nq, sizeof *q);
    size_t calls = (size_t)rounds * TARGETS;
    double *times = calloc(calls, sizeof *times);
    if (q == NULL || times == NULL || rounds < 1) {
        armcomp_model_free(model);
        return 1;
    }
    for (size_t c = 0; c < calls; c++) {
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        ArmcompStatus s = armcomp_compensate(model, targets[c % TARGETS], NULL,
                                             ARMCOMP_FRAME_MEASUREMENT, NULL, q, nq, message,
                                             sizeof message);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        if (s != ARMCOMP_STATUS_OK) {
            fprintf(stderr, "target %zu: status %d: %s\n", c % TARGETS + 1, (int)s, message);
            return 1;
        }
        times[c] = (t1.tv_sec - t0.tv_sec) * 1e6 + (t1.tv_nsec - t0.tv_nsec) * 1e-3;
    }
    qsort(times, calls, sizeof *times, compare);
    printf("calls %zu median_us %.2f p99_us %.2f max_us %.2f\n", calls, times[calls / 2],
           times[calls * 99 / 100], times[calls - 1]);
    free(q);
    free(times);
    armcomp_model_free(model);
    return 0;
}
