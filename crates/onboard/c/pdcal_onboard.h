/* pdcal-onboard: the onboard Sun-vector core's C ABI (single precision).
 *
 * The Sun direction in the body frame from calibrated photodiodes, with Earth albedo
 * compensated: weighted least squares over the lit photodiodes, the albedo of a reflectivity
 * grid (or a uniform Earth) subtracted at each pass. No allocation, no panic: every input
 * gives an estimate or a validity code saying why not.
 *
 * Link the static library built from crates/onboard/c/staticlib (a no_std Rust library).
 * The layouts below are checked against the Rust declarations by crates/onboard/tests/c_abi.rs.
 */
#ifndef PDCAL_ONBOARD_H
#define PDCAL_ONBOARD_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Most photodiodes one call takes. */
#define PDCAL_MAX_PHOTODIODES 64

/* Validity codes (pdcal_sun_estimate.validity and the return of pdcal_estimate_sun). */
#define PDCAL_VALID 0u               /* a Sun direction the outputs agree on */
#define PDCAL_ECLIPSE 1u             /* no photodiode lit */
#define PDCAL_TOO_FEW_LIT 2u         /* one or two lit: direction not determined */
#define PDCAL_DEGENERATE_GEOMETRY 3u /* lit normals nearly coplanar */
#define PDCAL_CONTRADICTORY 4u       /* outputs contradict each other */
#define PDCAL_DIM 5u                 /* less light than the full Sun: penumbra, shadow */
#define PDCAL_INVALID_INPUT 6u       /* an input is not usable; nothing estimated */

/* Albedo model used (pdcal_sun_estimate.albedo). */
#define PDCAL_ALBEDO_BOUND 0u   /* no Earth: outputs above the albedo bound only */
#define PDCAL_ALBEDO_UNIFORM 1u /* a uniform Earth */
#define PDCAL_ALBEDO_GRID 2u    /* the reflectivity grid */

/* One photodiode's calibration. */
typedef struct {
    float scale_v;            /* output at normal incidence at 1 AU, V */
    float normal_body[3];     /* unit normal, body frame */
    float dark_v;             /* output without light, V */
    float fov_half_angle_rad; /* no light beyond it; pi/2 for a cosine detector */
    float noise_v;            /* output noise, 1-sigma, V */
    float scale_sigma_v;      /* the calibration's 1-sigma of scale_v, V */
    float normal_sigma_rad;   /* the calibration's 1-sigma of the normal, rad */
    bool enabled;             /* false: the channel is not used */
} pdcal_photodiode;

typedef struct {
    uint32_t count; /* photodiodes in use, at most PDCAL_MAX_PHOTODIODES */
    pdcal_photodiode photodiodes[PDCAL_MAX_PHOTODIODES];
} pdcal_calibration;

/* Reflectivity grid: n_lat rows from the south pole by n_lon columns from -180 deg,
 * reflectivity = byte / 255, Earth-fixed. */
typedef struct {
    uint32_t n_lat;
    uint32_t n_lon;
    const uint8_t *cells;
} pdcal_grid;

/* The Earth as the flight software sees it. */
typedef struct {
    float earth_body[3];          /* unit vector toward the Earth's centre, body frame */
    float orbit_radius_km;        /* distance from the Earth's centre, km */
    uint32_t has_rotation;        /* non-zero when ecef_from_body is given */
    float ecef_from_body[3][3];   /* v_ecef = M v_body, rows */
    const pdcal_grid *grid;       /* NULL: uniform Earth */
} pdcal_earth;

typedef struct {
    float lit_sigmas;            /* lit when the corrected output exceeds this many sigmas */
    float min_singular_value;    /* of the used unit normals */
    uint32_t albedo_passes;      /* solve-then-recompute-the-albedo passes (at most 16) */
    float albedo_relative_sigma; /* albedo model error, fraction of the predicted albedo */
    float uniform_reflectivity;  /* reflectivity of a uniform Earth */
    float albedo_bound;          /* without the Earth: largest albedo any photodiode gets */
    float sun_distance_factor;   /* (1 AU / r_sun)^2 */
    float magnitude_tolerance;   /* accepted departure of |s| from 1 */
    float max_misfit_sigmas;     /* residuals beyond this (as a normal deviate): contradictory */
} pdcal_options;

typedef struct {
    float sun_body[3];       /* unit Sun direction, body frame */
    float magnitude;         /* |s| before normalising */
    float covariance[3][3];  /* of the unit direction, rad^2 */
    float cone_sigma_rad;    /* 1-sigma cone, rad */
    uint64_t used_mask;      /* bit i: photodiode i used */
    uint32_t n_used;
    float misfit;            /* normalised residual sum of squares */
    uint32_t validity;       /* PDCAL_VALID ... */
    uint32_t albedo;         /* PDCAL_ALBEDO_... */
} pdcal_sun_estimate;

/* Writes the default options to out (nothing when NULL). */
void pdcal_default_options(pdcal_options *out);

/* The Sun vector from n_outputs outputs (V); earth and options may be NULL (no albedo
 * compensation; the default options). Writes the estimate to out (when not NULL) and
 * returns its validity. */
uint32_t pdcal_estimate_sun(const float *outputs_v, uint32_t n_outputs,
                            const pdcal_calibration *calibration, const pdcal_earth *earth,
                            const pdcal_options *options, pdcal_sun_estimate *out);

#ifdef __cplusplus
}
#endif

#endif /* PDCAL_ONBOARD_H */
