/* Closed-form one-bounce scenes for the physics tests (tests/unit/test_physics.c on the CPU twins,
   tests/gl/gltest_physics.c through gim_update): open scenes of a few grey quads under a sun or
   a spot, where the exact indirect light has a closed form.

   Exact one bounce: each quad q is Lambertian (albedo rho_q, two-sided, lit on the side that
   faces the light). A point y of q leaves L(y) = rho_q E_dir(y) / pi, E_dir the direct
   irradiance (sun: E |n_q . s|; spot: I |n_q . w| / d^2 inside the cone; 0 in shadow). A
   receiver p (normal n_p) gets
     E_ind(p) = sum_q sum_cells L(cell centre) pi F(p -> cell),
   F by Lambert's contour formula (exact for a polygon in front of p). A uniformly lit quad is
   one cell, so the sun scenes without shadows are exact to rounding; a quad with a shadow
   boundary or a spot's falloff is split into PHYS_CELLS^2 cells, where the only error is L's
   variation inside a cell (measured below 0.2% against 2 x PHYS_CELLS). The receiver leaves
   rho_p / pi E_ind.

   Scenes (lengths in units of the base geometry, then p' = scale p + offset; the spot's
   intensity is scaled by scale^2 so the light's values do not depend on the scale):
     corner  floor [0,6] x [-3,3] (y = 0, albedo 0.8), wall x = 0, y in [0,1.5] (albedo 0.6),
             meeting at a contact edge; sun from (0.6, 0.7, 0.3), a spot above the floor, or a
             point light (a bulb at (1.5, 1.2, 0.4): gimany's six cube faces); the
             floor is wide against the wall, so the default cache spacing (diagonal / 32 = 0.27)
             is coarse against the distances to the wall, as in an open scene;
     plates  a lit plate [-1,1]^2 (y = 0) under a smaller plate [-0.4,0.4]^2 at y = 0.5 facing
             it; the sun comes in at 72 degrees so the upper plate's shadow misses the lower;
     patch   a 0.2 x 0.2 patch facing down at y = 0.3 over a lit plane [-1.5,1.5]^2; the
             patch's shadow on the plane is part of the closed form (sun or spot). */
#ifndef GIMANY_TESTS_PHYSICS_H
#define GIMANY_TESTS_PHYSICS_H
#include <math.h>
#include <string.h>
#include <stdint.h>

#if defined(__GNUC__) || defined(__clang__)
#define PHYS_UNUSED __attribute__((unused))
#else
#define PHYS_UNUSED
#endif

#define PHYS_MAX_QUADS 4
#define PHYS_CELLS 48
#define PHYS_PI 3.14159265358979323846

typedef enum phys_which {
    PHYS_CORNER_SUN, PHYS_CORNER_SPOT, PHYS_PLATES_SUN, PHYS_PATCH_SUN, PHYS_PATCH_SPOT, PHYS_CORNER_POINT, PHYS_SCENE_COUNT
} phys_which;

typedef struct phys_quad {
    double o[3], u[3], v[3];   /* corner and edges; the front normal normalize(u x v) faces the open side */
    float albedo;
    int receiver;              /* 1: the tests look at this quad */
} phys_quad;

typedef struct phys_scene {
    const char *name;
    phys_quad quad[PHYS_MAX_QUADS];
    int quad_count;
    int spot;                  /* 0: sun; 1: spot; 2: point light (a spot whose cone is every direction) */
    double sun[3];             /* unit, towards the sun */
    double irradiance;         /* sun E */
    double spot_pos[3], spot_axis[3], cone, intensity;
    int uniform;               /* 1: every quad uniformly lit (one cell is exact) */
} phys_scene;

static void phys__unit(double *a) {
    double l = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    a[0] /= l; a[1] /= l; a[2] /= l;
}
static double phys__dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void phys__cross(const double *a, const double *b, double *c) {
    c[0] = a[1] * b[2] - a[2] * b[1]; c[1] = a[2] * b[0] - a[0] * b[2]; c[2] = a[0] * b[1] - a[1] * b[0];
}
static PHYS_UNUSED void phys_normal(const phys_quad *q, double *n) { phys__cross(q->u, q->v, n); phys__unit(n); }

static void phys__quad(phys_scene *s, double ox, double oy, double oz, double ux, double uy, double uz, double vx,
                       double vy, double vz, float albedo, int receiver) {
    phys_quad *q = &s->quad[s->quad_count++];
    q->o[0] = ox; q->o[1] = oy; q->o[2] = oz;
    q->u[0] = ux; q->u[1] = uy; q->u[2] = uz;
    q->v[0] = vx; q->v[1] = vy; q->v[2] = vz;
    q->albedo = albedo;
    q->receiver = receiver;
}

/* Scene `which` at the given scale and offset. */
static PHYS_UNUSED void phys_scene_make(phys_which which, double scale, const double offset[3], phys_scene *s) {
    int i, a;
    memset(s, 0, sizeof *s);
    s->irradiance = 2.0;
    switch (which) {
    case PHYS_CORNER_SUN:
    case PHYS_CORNER_SPOT:
    case PHYS_CORNER_POINT:
        s->name = which == PHYS_CORNER_SUN ? "corner, sun" : which == PHYS_CORNER_SPOT ? "corner, spot" : "corner, point";
        phys__quad(s, 0, 0, 3, 6, 0, 0, 0, 0, -6, 0.8f, 1);     /* floor, normal +y */
        phys__quad(s, 0, 0, -3, 0, 1.5, 0, 0, 0, 6, 0.6f, 1);   /* wall, normal +x */
        break;
    case PHYS_PLATES_SUN:
        s->name = "plates, sun";
        phys__quad(s, -1, 0, 1, 2, 0, 0, 0, 0, -2, 0.8f, 0);            /* lit plate, +y */
        phys__quad(s, -0.4, 0.5, -0.4, 0.8, 0, 0, 0, 0, 0.8, 0.7f, 1);  /* upper plate, -y */
        break;
    case PHYS_PATCH_SUN:
    case PHYS_PATCH_SPOT:
        s->name = which == PHYS_PATCH_SUN ? "patch, sun" : "patch, spot";
        phys__quad(s, -1.5, 0, 1.5, 3, 0, 0, 0, 0, -3, 0.8f, 0);        /* lit plane, +y */
        phys__quad(s, -0.1, 0.3, -0.1, 0.2, 0, 0, 0, 0, 0.2, 0.7f, 1);  /* patch, -y */
        break;
    default: break;
    }
    if (which == PHYS_CORNER_SUN) { s->sun[0] = 0.6; s->sun[1] = 0.7; s->sun[2] = 0.3; s->uniform = 1; }
    if (which == PHYS_PLATES_SUN) { s->sun[0] = sin(72.0 * PHYS_PI / 180.0); s->sun[1] = cos(72.0 * PHYS_PI / 180.0); s->uniform = 1; }
    if (which == PHYS_PATCH_SUN) { s->sun[0] = 0.5; s->sun[1] = 1.0; s->sun[2] = 0.2; }
    phys__unit(s->sun);
    if (which == PHYS_CORNER_SPOT || which == PHYS_PATCH_SPOT) {
        double target[3] = {0.5, 0.0, 0.0};
        s->spot = 1;
        s->spot_pos[0] = 1.0; s->spot_pos[1] = 3.0; s->spot_pos[2] = 0.0;
        if (which == PHYS_PATCH_SPOT) { s->spot_pos[0] = 1.2; s->spot_pos[1] = 1.5; target[0] = 0.0; }
        for (a = 0; a < 3; ++a) s->spot_axis[a] = target[a] - s->spot_pos[a];
        phys__unit(s->spot_axis);
        s->cone = 1.2;
        s->intensity = 6.0 * scale * scale;
        for (a = 0; a < 3; ++a) s->spot_pos[a] = s->spot_pos[a] * scale + offset[a];
    }
    if (which == PHYS_CORNER_POINT) {   /* a bulb 1.2 above the floor, 1.5 from the wall: every cube face sees the floor */
        s->spot = 2;
        s->spot_pos[0] = 1.5; s->spot_pos[1] = 1.2; s->spot_pos[2] = 0.4;
        s->spot_axis[1] = -1.0;
        s->cone = PHYS_PI;
        s->intensity = 4.0 * scale * scale;
        for (a = 0; a < 3; ++a) s->spot_pos[a] = s->spot_pos[a] * scale + offset[a];
    }
    for (i = 0; i < s->quad_count; ++i)
        for (a = 0; a < 3; ++a) {
            s->quad[i].o[a] = s->quad[i].o[a] * scale + offset[a];
            s->quad[i].u[a] *= scale;
            s->quad[i].v[a] *= scale;
        }
}

/* The light as gimany takes it (rsm_size texels); for the sun, extent 0 covers the scene. */
static PHYS_UNUSED gim_light phys_light(const phys_scene *s, uint32_t rsm_size) {
    gim_light l;
    memset(&l, 0, sizeof l);
    l.rsm_size = rsm_size;
    if (s->spot) {
        l.type = s->spot == 2 ? GIM_LIGHT_POINT : GIM_LIGHT_SPOT;
        l.intensity = (float)s->intensity;
        l.position = gim_v3((float)s->spot_pos[0], (float)s->spot_pos[1], (float)s->spot_pos[2]);
        l.direction = gim_v3((float)s->spot_axis[0], (float)s->spot_axis[1], (float)s->spot_axis[2]);
        l.cone_angle = (float)s->cone;
    } else {
        l.type = GIM_LIGHT_DIRECTIONAL;
        l.irradiance = (float)s->irradiance;
        l.direction = gim_v3((float)s->sun[0], (float)s->sun[1], (float)s->sun[2]);
    }
    return l;
}

/* Two triangles per quad: positions[quad_count * 18], albedo[quad_count * 6] (grey rgb per
   triangle); returns the triangle count. */
static PHYS_UNUSED uint32_t phys_triangles(const phys_scene *s, float *positions, float *albedo) {
    int i, a, t;
    for (i = 0; i < s->quad_count; ++i) {
        const phys_quad *q = &s->quad[i];
        double c[4][3];
        static const int tri[2][3] = {{0, 1, 2}, {0, 2, 3}};
        for (a = 0; a < 3; ++a) {
            c[0][a] = q->o[a];
            c[1][a] = q->o[a] + q->u[a];
            c[2][a] = q->o[a] + q->u[a] + q->v[a];
            c[3][a] = q->o[a] + q->v[a];
        }
        for (t = 0; t < 2; ++t) {
            int k;
            for (k = 0; k < 3; ++k)
                for (a = 0; a < 3; ++a) positions[(i * 2 + t) * 9 + k * 3 + a] = (float)c[tri[t][k]][a];
            if (albedo)
                for (a = 0; a < 3; ++a) albedo[(i * 2 + t) * 3 + a] = q->albedo;
        }
    }
    return (uint32_t)s->quad_count * 2u;
}

/* Does the segment from y towards the light (to the spot, or along the sun) hit another quad? */
static int phys__shadowed(const phys_scene *s, int self, const double *y) {
    int i, a;
    double d[3], tmax;
    if (s->spot) {
        for (a = 0; a < 3; ++a) d[a] = s->spot_pos[a] - y[a];
        tmax = 1.0;
    } else {
        for (a = 0; a < 3; ++a) d[a] = s->sun[a];
        tmax = 1e300;
    }
    for (i = 0; i < s->quad_count; ++i) {
        const phys_quad *q = &s->quad[i];
        double n[3], den, t, h[3], uu, vv, uv, hu, hv, det, bu, bv;
        if (i == self) continue;
        phys__cross(q->u, q->v, n);
        den = phys__dot(n, d);
        if (fabs(den) < 1e-300) continue;
        for (a = 0; a < 3; ++a) h[a] = q->o[a] - y[a];
        t = phys__dot(n, h) / den;
        if (!(t > 1e-9 && t < tmax)) continue;
        for (a = 0; a < 3; ++a) h[a] = y[a] + t * d[a] - q->o[a];
        uu = phys__dot(q->u, q->u); vv = phys__dot(q->v, q->v); uv = phys__dot(q->u, q->v);
        hu = phys__dot(h, q->u); hv = phys__dot(h, q->v);
        det = uu * vv - uv * uv;
        bu = (hu * vv - hv * uv) / det;
        bv = (hv * uu - hu * uv) / det;
        if (bu >= 0.0 && bu <= 1.0 && bv >= 0.0 && bv <= 1.0) return 1;
    }
    return 0;
}

/* Direct irradiance at point y of quad `self` (either side: two-sided) and, into lit_n, the
   normal of its lit side. */
static double phys_direct(const phys_scene *s, int self, const double *y, double *lit_n) {
    double n[3], w[3], d2, c;
    int a;
    phys_normal(&s->quad[self], n);
    if (s->spot) {
        for (a = 0; a < 3; ++a) w[a] = s->spot_pos[a] - y[a];
        d2 = phys__dot(w, w);
        phys__unit(w);
        if (-phys__dot(w, s->spot_axis) < cos(s->cone)) return 0.0;
    } else {
        for (a = 0; a < 3; ++a) w[a] = s->sun[a];
        d2 = 1.0;
    }
    c = phys__dot(n, w);
    for (a = 0; a < 3; ++a) lit_n[a] = c >= 0.0 ? n[a] : -n[a];
    if (c == 0.0 || phys__shadowed(s, self, y)) return 0.0;
    return (s->spot ? s->intensity / d2 : s->irradiance) * fabs(c);
}

/* Lambert's formula: the form factor from p (unit normal n) to a polygon in front of it. */
static double phys_form_factor(const double *p, const double *n, const double poly[][3], int count) {
    double sum = 0.0;
    int i, a;
    for (i = 0; i < count; ++i) {
        double r0[3], r1[3], c[3], lc;
        for (a = 0; a < 3; ++a) { r0[a] = poly[i][a] - p[a]; r1[a] = poly[(i + 1) % count][a] - p[a]; }
        phys__unit(r0);
        phys__unit(r1);
        phys__cross(r0, r1, c);
        lc = sqrt(phys__dot(c, c));
        if (lc == 0.0) continue;
        sum += atan2(lc, phys__dot(r0, r1)) * phys__dot(n, c) / lc;
    }
    return fabs(sum) / (2.0 * PHYS_PI);
}

/* What the cell [u0,u1] x [v0,v1] of quad q sends to p (normal n): L(centre) pi F, or with p
   NULL the power it reflects, rho E_dir(centre) area; a cell whose corners disagree on being
   lit (a shadow's or the cone's edge crosses it) is split in four, down to depth 6. */
static double phys__cell(const phys_scene *s, int q, const double *p, const double *n, double u0, double u1,
                         double v0, double v1, int depth) {
    const phys_quad *qq = &s->quad[q];
    double poly[4][3], y[3], lit_n[3], ed, rel[3], corner_n[3];
    int a, k, lit = 0;
    static const int cu[4] = {0, 1, 1, 0}, cv[4] = {0, 0, 1, 1};
    for (k = 0; k < 4; ++k) {
        for (a = 0; a < 3; ++a) poly[k][a] = qq->o[a] + qq->u[a] * (cu[k] ? u1 : u0) + qq->v[a] * (cv[k] ? v1 : v0);
        lit += phys_direct(s, q, poly[k], corner_n) > 0.0;
    }
    if (depth < 6 && lit != 0 && lit != 4) {
        double um = 0.5 * (u0 + u1), vm = 0.5 * (v0 + v1);
        return phys__cell(s, q, p, n, u0, um, v0, vm, depth + 1) + phys__cell(s, q, p, n, um, u1, v0, vm, depth + 1) +
               phys__cell(s, q, p, n, um, u1, vm, v1, depth + 1) + phys__cell(s, q, p, n, u0, um, vm, v1, depth + 1);
    }
    for (a = 0; a < 3; ++a) y[a] = qq->o[a] + qq->u[a] * 0.5 * (u0 + u1) + qq->v[a] * 0.5 * (v0 + v1);
    ed = phys_direct(s, q, y, lit_n);
    if (!(ed > 0.0)) return 0.0;
    if (!p) {
        double c[3];
        phys__cross(qq->u, qq->v, c);
        return qq->albedo * ed * sqrt(phys__dot(c, c)) * (u1 - u0) * (v1 - v0);
    }
    for (a = 0; a < 3; ++a) rel[a] = p[a] - y[a];
    if (!(phys__dot(lit_n, rel) > 0.0)) return 0.0;   /* p behind the lit side */
    return qq->albedo * ed * phys_form_factor(p, n, (const double(*)[3])poly, 4);   /* L pi F, L = rho E / pi */
}

/* Exact one-bounce irradiance at p (normal n) from every quad but `self` (-1: none), each quad
   in cells^2 cells (split further along shadow and cone edges). */
static double phys_exact_irradiance_cells(const phys_scene *s, int self, const double *p, const double *n, int cells) {
    double e = 0.0;
    int q, i, j;
    for (q = 0; q < s->quad_count; ++q) {
        const phys_quad *qq = &s->quad[q];
        double nq[3], rel[3];
        int a;
        if (q == self) continue;
        /* a point in the quad's own plane (float-rounded) sees none of it */
        phys_normal(qq, nq);
        for (a = 0; a < 3; ++a) rel[a] = p[a] - qq->o[a];
        if (fabs(phys__dot(nq, rel)) <= 1e-6 * sqrt(phys__dot(qq->u, qq->u) + phys__dot(qq->v, qq->v))) continue;
        for (i = 0; i < cells; ++i)
            for (j = 0; j < cells; ++j)
                e += phys__cell(s, q, p, n, (double)i / cells, (double)(i + 1) / cells, (double)j / cells,
                                (double)(j + 1) / cells, 0);
    }
    return e;
}
static PHYS_UNUSED double phys_exact_irradiance(const phys_scene *s, int self, const double *p, const double *n) {
    return phys_exact_irradiance_cells(s, self, p, n, s->uniform ? 1 : PHYS_CELLS);
}

/* The direct power the quads reflect (sum of rho E_dir dA), by the same cells: what the RSM's
   texels must sum to when the RSM covers every quad. */
static double phys_reflected_power_cells(const phys_scene *s, int cells) {
    double power = 0.0;
    int q, i, j;
    for (q = 0; q < s->quad_count; ++q)
        for (i = 0; i < cells; ++i)
            for (j = 0; j < cells; ++j)
                power += phys__cell(s, q, NULL, NULL, (double)i / cells, (double)(i + 1) / cells, (double)j / cells,
                                    (double)(j + 1) / cells, 0);
    return power;
}
static PHYS_UNUSED double phys_reflected_power(const phys_scene *s) {
    return phys_reflected_power_cells(s, s->uniform ? 1 : PHYS_CELLS);
}

/* Distance from p to the corner's contact edge (where floor and wall meet) in units of the
   base geometry; -1 for the scenes without one. */
static PHYS_UNUSED double phys_contact_distance(const phys_scene *s, const double *p) {
    const phys_quad *w = &s->quad[1];
    double v[3], r[3], c[3], lv;
    int a;
    if (strncmp(s->name, "corner", 6) != 0) return -1.0;
    for (a = 0; a < 3; ++a) { v[a] = w->v[a]; r[a] = p[a] - w->o[a]; }
    lv = sqrt(phys__dot(v, v));
    phys__cross(r, v, c);
    return sqrt(phys__dot(c, c)) / lv / (lv / 6.0);   /* the wall's edge is 6 long in the base */
}

/* Median of values[count] (sorted in place). */
static int phys__cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}
static PHYS_UNUSED double phys_median(double *values, size_t count) {
    qsort(values, count, sizeof *values, phys__cmp);
    return count ? (count % 2 ? values[count / 2] : 0.5 * (values[count / 2 - 1] + values[count / 2])) : 0.0;
}

#endif
