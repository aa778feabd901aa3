/* Runs the onboard core on recorded rows and prints each estimate's bits, for
 * crates/onboard/tests/c_abi.rs to compare with the Rust results.
 *
 * Usage: replay ROWS_FILE
 *   layout   -> prints sizeof/offsetof of every structure (checked against Rust)
 *   ROWS_FILE: "count N", N lines "pd scale nx ny nz dark fov noise ssig nsig enabled",
 *   optionally "grid n_lat n_lon" and n_lat*n_lon byte values, then rows
 *   "row y_1..y_N has_earth ex ey ez r has_rot m00 m01 .. m22".
 * Prints per row: validity albedo n_used used_mask, then the bits of sun_body[0..3],
 * magnitude, cone_sigma_rad and misfit, in hex. */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pdcal_onboard.h"

static unsigned bits(float x) {
    unsigned u;
    memcpy(&u, &x, sizeof u);
    return u;
}

static int layout(void) {
    printf("photodiode %zu %zu %zu\n", sizeof(pdcal_photodiode),
           offsetof(pdcal_photodiode, normal_sigma_rad), offsetof(pdcal_photodiode, enabled));
    printf("calibration %zu %zu\n", sizeof(pdcal_calibration),
           offsetof(pdcal_calibration, photodiodes));
    printf("grid %zu %zu\n", sizeof(pdcal_grid), offsetof(pdcal_grid, cells));
    printf("earth %zu %zu %zu\n", sizeof(pdcal_earth), offsetof(pdcal_earth, ecef_from_body),
           offsetof(pdcal_earth, grid));
    printf("options %zu %zu %zu\n", sizeof(pdcal_options), offsetof(pdcal_options, albedo_passes),
           offsetof(pdcal_options, max_misfit_sigmas));
    printf("estimate %zu %zu %zu %zu\n", sizeof(pdcal_sun_estimate),
           offsetof(pdcal_sun_estimate, used_mask), offsetof(pdcal_sun_estimate, validity),
           offsetof(pdcal_sun_estimate, albedo));
    return 0;
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: replay ROWS_FILE | layout\n");
        return 2;
    }
    if (strcmp(argv[1], "layout") == 0) {
        return layout();
    }
    FILE *f = fopen(argv[1], "r");
    if (!f) {
        perror(argv[1]);
        return 2;
    }
    static pdcal_calibration cal;
    static uint8_t cells[1800 * 3600];
    pdcal_grid grid = {0, 0, cells};
    int has_grid = 0;
    char word[16];
    pdcal_options options;
    pdcal_default_options(&options);
    while (fscanf(f, "%15s", word) == 1) {
        if (strcmp(word, "count") == 0) {
            if (fscanf(f, "%u", &cal.count) != 1) return 3;
        } else if (strcmp(word, "pd") == 0) {
            static unsigned k = 0;
            pdcal_photodiode *p = &cal.photodiodes[k++ % PDCAL_MAX_PHOTODIODES];
            int enabled;
            if (fscanf(f, "%f %f %f %f %f %f %f %f %f %d", &p->scale_v, &p->normal_body[0],
                       &p->normal_body[1], &p->normal_body[2], &p->dark_v,
                       &p->fov_half_angle_rad, &p->noise_v, &p->scale_sigma_v,
                       &p->normal_sigma_rad, &enabled) != 10)
                return 3;
            p->enabled = enabled != 0;
        } else if (strcmp(word, "grid") == 0) {
            if (fscanf(f, "%u %u", &grid.n_lat, &grid.n_lon) != 2) return 3;
            if ((size_t)grid.n_lat * grid.n_lon > sizeof cells) return 3;
            for (size_t i = 0; i < (size_t)grid.n_lat * grid.n_lon; i++) {
                unsigned v;
                if (fscanf(f, "%u", &v) != 1) return 3;
                cells[i] = (uint8_t)v;
            }
            has_grid = 1;
        } else if (strcmp(word, "row") == 0) {
            float y[PDCAL_MAX_PHOTODIODES];
            for (unsigned i = 0; i < cal.count && i < PDCAL_MAX_PHOTODIODES; i++)
                if (fscanf(f, "%f", &y[i]) != 1) return 3;
            pdcal_earth earth;
            int has_earth;
            if (fscanf(f, "%d %f %f %f %f %u", &has_earth, &earth.earth_body[0],
                       &earth.earth_body[1], &earth.earth_body[2], &earth.orbit_radius_km,
                       &earth.has_rotation) != 6)
                return 3;
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++)
                    if (fscanf(f, "%f", &earth.ecef_from_body[r][c]) != 1) return 3;
            earth.grid = has_grid ? &grid : NULL;
            pdcal_sun_estimate e;
            uint32_t v = pdcal_estimate_sun(y, cal.count, &cal, has_earth ? &earth : NULL,
                                            &options, &e);
            if (v != e.validity) return 4;
            printf("%u %u %u %llu %08x %08x %08x %08x %08x %08x\n", e.validity, e.albedo,
                   e.n_used, (unsigned long long)e.used_mask, bits(e.sun_body[0]),
                   bits(e.sun_body[1]), bits(e.sun_body[2]), bits(e.magnitude),
                   bits(e.cone_sigma_rad), bits(e.misfit));
        } else {
            fprintf(stderr, "unknown record %s\n", word);
            return 3;
        }
    }
    fclose(f);
    return 0;
}
