/*
 * A quarter-car suspension on a road-simulator rig (a four-poster's one post), for the framework
 * of model.h (FMI 2.0 co-simulation and model exchange).
 *
 * A hydraulic post moves the tyre's foot by z_r(t) [m] (the input). Two masses: the sprung mass
 * (body, m_s + m_extra [kg]) at z_s [m] and the unsprung mass (wheel, m_u [kg]) at z_u [m]. The
 * suspension (spring k_s [N/m], damper c_s [N s/m]) acts between body and wheel, the tyre (k_t
 * [N/m], c_t [N s/m]) between wheel and post. Gravity-free: every position is a deflection about
 * the static equilibrium, z positive up. Suspension deflection x = z_s - z_u [m]: x > 0 is
 * extension (rebound), x < 0 compression (bump); relative velocity v_rel = v_s - v_u [m/s].
 *
 * Force of the suspension on the body [N] (the opposite acts on the wheel):
 *     F_s = -(k_s x + k3 x^3)                                  spring, progressive with k3
 *           - c_s (1 + a sigma(v_rel)) v_rel                   damper, a = damper_asymmetry
 *           - F_c tanh(v_rel / V_EPS)                          Coulomb friction of the seals
 *           + k_bump max(0, -x - bump_stop_gap)                bump stop in compression
 * with sigma(v) = (1 + tanh(v / V_EPS)) / 2 (1 in rebound, 0 in compression), V_EPS = 0.01 m/s.
 * Force of the tyre on the wheel [N], about its static load F_static = (m_s + m_extra + m_u) G:
 *     F_t = k_t (z_r - z_u) + c_t (dz_r/dt - v_u)              tyre_lift = 0
 *     F_t = max(0, F_static + F_t) - F_static                  tyre_lift = 1 (cannot pull)
 * (intermediate tyre_lift values blend the two linearly). Equations of motion:
 *     (m_s + m_extra) a_s = F_s + F_body
 *     m_u a_u = -F_s + F_t + F_wheel
 * At the neutral effect values (F_c = k3 = damper_asymmetry = k_bump = tyre_lift = m_extra = 0)
 * the model is exactly the linear quarter car.
 *
 * The input z_r is held (zero-order hold) over each communication step: within a step the post
 * does not move (dz_r/dt = 0). The held input is a staircase, whose derivative is a Dirac impulse
 * at each change: when z_r differs from the value of the previous step, the tyre damper gives
 * the wheel the impulse c_t (z_r - z_r_prev) [N s] (its velocity jumps by that over m_u), so the
 * model is the exact response of the quarter car to the staircase (no loss of the c_t dz_r/dt
 * term). With tyre_lift = 1 the impulse is not given while the tyre is off the post.
 *
 * Integration: fixed-step RK4 of at most h_int [s] (the communication step is cut into
 * ceil(h / h_int) equal sub-steps). Outputs at each communication point: a_body [m/s^2] and
 * a_wheel [m/s^2] (the right-hand side's value at that instant, with the input held over the
 * step just done) and x_susp [m]; locals z_body, v_body, z_wheel, v_wheel and F_tyre (the tyre's
 * total contact force, static load included [N]).
 *
 * Initial state: at rest on the post's initial position, z_s = z_u = z_r(t0), v_s = v_u = 0
 * (z_r(t0) = 0 gives the state at rest at zero).
 */
#include <math.h>
#include <stdio.h>

#include "model.h"

/* value references (= index into m->r), in the order of modelDescription.xml */
enum {
    /* parameters: body */
    VR_M_S = 0,         /* sprung (body) mass [kg] */
    /* parameters: wheel and tyre */
    VR_M_U,             /* unsprung (wheel) mass [kg] */
    /* parameters: suspension */
    VR_K_S,             /* suspension spring stiffness [N/m] */
    VR_C_S,             /* suspension damper coefficient (compression; rebound with asymmetry) [N s/m] */
    /* parameters: tyre */
    VR_K_T,             /* tyre vertical stiffness [N/m] */
    VR_C_T,             /* tyre vertical damping [N s/m] */
    /* effects (neutral values in brackets) */
    VR_F_C,             /* Coulomb friction of the damper's seals [N] (0) */
    VR_K3,              /* cubic (progressive) spring coefficient [N/m^3] (0) */
    VR_DAMPER_ASYM,     /* rebound damping (1 + a) c_s against compression c_s [-] (0) */
    VR_BUMP_GAP,        /* compression at which the bump stop engages [m] (any; 0.03) */
    VR_K_BUMP,          /* bump-stop stiffness [N/m] (0) */
    VR_TYRE_LIFT,       /* 0: the tyre may pull, 1: it cannot (loses contact) [-] (0) */
    VR_M_EXTRA,         /* payload on the body [kg] (0) */
    /* solver */
    VR_H_INT,           /* internal RK4 step, upper bound [s] */
    /* inputs */
    VR_Z_R,             /* post (road) displacement [m] */
    VR_F_BODY,          /* unknown force on the body, up [N] */
    VR_F_WHEEL,         /* unknown force on the wheel, up [N] */
    /* outputs */
    VR_A_BODY,          /* body acceleration [m/s^2] */
    VR_X_SUSP,          /* suspension deflection z_s - z_u [m] */
    VR_A_WHEEL,         /* wheel acceleration [m/s^2] */
    /* locals */
    VR_Z_BODY,          /* body displacement [m] */
    VR_V_BODY,          /* body velocity [m/s] */
    VR_Z_WHEEL,         /* wheel displacement [m] */
    VR_V_WHEEL,         /* wheel velocity [m/s] */
    VR_F_TYRE,          /* tyre contact force, static load included [N] */
    N_REALS
};

/* state layout in m->x */
enum {
    X_Z_S = 0,          /* body displacement [m] */
    X_V_S,              /* body velocity [m/s] */
    X_Z_U,              /* wheel displacement [m] */
    X_V_U,              /* wheel velocity [m/s] */
    N_CONT,             /* number of continuous states */
    X_Z_R_PREV = N_CONT /* the post displacement held over the previous step [m] */
};

#define G 9.81           /* gravitational acceleration [m/s^2] (static tyre load only) */
#define V_EPS 0.01       /* velocity scale of the tanh smoothings [m/s] */
#define MAX_SUBSTEPS 100000000.0 /* more sub-steps in one communication step is a mistake */

/* the parameters of one evaluation, read from m->r */
typedef struct {
    double m_body;      /* m_s + m_extra [kg] */
    double m_u;         /* [kg] */
    double k_s, c_s;    /* [N/m], [N s/m] */
    double k_t, c_t;    /* [N/m], [N s/m] */
    double f_c;         /* [N] */
    double k3;          /* [N/m^3] */
    double asym;        /* [-] */
    double gap, k_bump; /* [m], [N/m] */
    double lift;        /* [-] */
    double f_static;    /* static tyre load [N] */
} Params;

static Params read_params(const Instance *m) {
    Params p;
    p.m_body = m->r[VR_M_S] + m->r[VR_M_EXTRA];
    p.m_u = m->r[VR_M_U];
    p.k_s = m->r[VR_K_S];
    p.c_s = m->r[VR_C_S];
    p.k_t = m->r[VR_K_T];
    p.c_t = m->r[VR_C_T];
    p.f_c = m->r[VR_F_C];
    p.k3 = m->r[VR_K3];
    p.asym = m->r[VR_DAMPER_ASYM];
    p.gap = m->r[VR_BUMP_GAP];
    p.k_bump = m->r[VR_K_BUMP];
    p.lift = m->r[VR_TYRE_LIFT];
    p.f_static = (m->r[VR_M_S] + m->r[VR_M_EXTRA] + m->r[VR_M_U]) * G;
    return p;
}

/* Set m->message and return 1 if a parameter is impossible, else return 0. */
static int check_params(Instance *m) {
    static const char *names[] = {"m_s", "m_u", "k_s", "c_s", "k_t", "c_t", "F_c", "k3",
                                  "damper_asymmetry", "bump_stop_gap", "k_bump", "tyre_lift",
                                  "m_extra", "h_int", "z_r", "F_body", "F_wheel"};
    for (int i = 0; i <= VR_F_WHEEL; i++) {
        if (!isfinite(m->r[i])) {
            snprintf(m->message, MESSAGE_SIZE, "%s = %g is not finite", names[i], m->r[i]);
            return 1;
        }
    }
    const double *r = m->r;
#define REQUIRE(cond, ...)                                  \
    do {                                                    \
        if (!(cond)) {                                      \
            snprintf(m->message, MESSAGE_SIZE, __VA_ARGS__); \
            return 1;                                       \
        }                                                   \
    } while (0)
    REQUIRE(r[VR_M_S] > 0.0, "m_s = %g kg: the body mass must be positive", r[VR_M_S]);
    REQUIRE(r[VR_M_U] > 0.0, "m_u = %g kg: the wheel mass must be positive", r[VR_M_U]);
    REQUIRE(r[VR_K_S] >= 0.0, "k_s = %g N/m: the spring stiffness must not be negative", r[VR_K_S]);
    REQUIRE(r[VR_C_S] >= 0.0, "c_s = %g N s/m: the damper coefficient must not be negative", r[VR_C_S]);
    REQUIRE(r[VR_K_T] > 0.0, "k_t = %g N/m: the tyre stiffness must be positive", r[VR_K_T]);
    REQUIRE(r[VR_C_T] >= 0.0, "c_t = %g N s/m: the tyre damping must not be negative", r[VR_C_T]);
    REQUIRE(r[VR_F_C] >= 0.0, "F_c = %g N: the seal friction must not be negative", r[VR_F_C]);
    REQUIRE(r[VR_DAMPER_ASYM] >= -1.0,
            "damper_asymmetry = %g: the rebound damping (1 + a) c_s must not be negative (a >= -1)",
            r[VR_DAMPER_ASYM]);
    REQUIRE(r[VR_BUMP_GAP] >= 0.0, "bump_stop_gap = %g m must not be negative", r[VR_BUMP_GAP]);
    REQUIRE(r[VR_K_BUMP] >= 0.0, "k_bump = %g N/m: the bump-stop stiffness must not be negative", r[VR_K_BUMP]);
    REQUIRE(r[VR_TYRE_LIFT] >= 0.0 && r[VR_TYRE_LIFT] <= 1.0,
            "tyre_lift = %g must be 0 (the tyre may pull) or 1 (it cannot), or in between", r[VR_TYRE_LIFT]);
    REQUIRE(r[VR_M_S] + r[VR_M_EXTRA] > 0.0,
            "m_s + m_extra = %g kg: the payload must not make the body's mass zero or negative",
            r[VR_M_S] + r[VR_M_EXTRA]);
    REQUIRE(r[VR_H_INT] > 0.0, "h_int = %g s: the internal step must be positive", r[VR_H_INT]);
#undef REQUIRE
    return 0;
}

/* The tyre's force on the wheel about its static load [N] at wheel position z_u [m], wheel
 * velocity v_u [m/s] and post position z_r [m] (the post at rest within a step). */
static double tyre_force(const Params *p, double z_u, double v_u, double z_r) {
    double f_lin = p->k_t * (z_r - z_u) - p->c_t * v_u;
    if (p->lift == 0.0) return f_lin;
    double f_contact = fmax(0.0, p->f_static + f_lin) - p->f_static;
    return (1.0 - p->lift) * f_lin + p->lift * f_contact;
}

/* The suspension's force on the body [N] at deflection x [m] and relative velocity v [m/s]. */
static double suspension_force(const Params *p, double x, double v) {
    double th = tanh(v / V_EPS);
    double spring = p->k_s * x + p->k3 * x * x * x;
    double damper = p->c_s * (1.0 + p->asym * 0.5 * (1.0 + th)) * v;
    double friction = p->f_c * th;
    double bump = p->k_bump * fmax(0.0, -x - p->gap);
    return -spring - damper - friction + bump;
}

/* Right-hand side: ds/dt of s = (z_s, v_s, z_u, v_u) with the inputs held. */
static void rhs(const Params *p, const double s[N_CONT], double z_r, double f_body, double f_wheel,
                double ds[N_CONT]) {
    double f_s = suspension_force(p, s[X_Z_S] - s[X_Z_U], s[X_V_S] - s[X_V_U]);
    double f_t = tyre_force(p, s[X_Z_U], s[X_V_U], z_r);
    ds[X_Z_S] = s[X_V_S];
    ds[X_V_S] = (f_s + f_body) / p->m_body;
    ds[X_Z_U] = s[X_V_U];
    ds[X_V_U] = (-f_s + f_t + f_wheel) / p->m_u;
}

/* Write the outputs and locals at the current state with the inputs in m->r. */
static void write_outputs(Instance *m, const Params *p) {
    const double *s = m->x;
    double ds[N_CONT];
    rhs(p, s, m->r[VR_Z_R], m->r[VR_F_BODY], m->r[VR_F_WHEEL], ds);
    m->r[VR_A_BODY] = ds[X_V_S];
    m->r[VR_X_SUSP] = s[X_Z_S] - s[X_Z_U];
    m->r[VR_A_WHEEL] = ds[X_V_U];
    m->r[VR_Z_BODY] = s[X_Z_S];
    m->r[VR_V_BODY] = s[X_V_S];
    m->r[VR_Z_WHEEL] = s[X_Z_U];
    m->r[VR_V_WHEEL] = s[X_V_U];
    m->r[VR_F_TYRE] = p->f_static + tyre_force(p, s[X_Z_U], s[X_V_U], m->r[VR_Z_R]);
}

int model_n_reals(void) { return N_REALS; }

void model_start_values(Instance *m) {
    for (int i = 0; i < N_REALS; i++) m->r[i] = 0.0;
    m->r[VR_M_S] = 300.0;      /* kg */
    m->r[VR_M_U] = 40.0;       /* kg */
    m->r[VR_K_S] = 20000.0;    /* N/m */
    m->r[VR_C_S] = 1500.0;     /* N s/m */
    m->r[VR_K_T] = 200000.0;   /* N/m */
    m->r[VR_C_T] = 50.0;       /* N s/m */
    m->r[VR_F_C] = 0.0;        /* N */
    m->r[VR_K3] = 0.0;         /* N/m^3 */
    m->r[VR_DAMPER_ASYM] = 0.0;
    m->r[VR_BUMP_GAP] = 0.03;  /* m */
    m->r[VR_K_BUMP] = 0.0;     /* N/m */
    m->r[VR_TYRE_LIFT] = 0.0;
    m->r[VR_M_EXTRA] = 0.0;    /* kg */
    m->r[VR_H_INT] = 1e-4;     /* s */
    m->r[VR_Z_R] = 0.0;        /* m */
    m->r[VR_F_BODY] = 0.0;     /* N */
    m->r[VR_F_WHEEL] = 0.0;    /* N */
}

int model_initialize(Instance *m) {
    if (check_params(m)) return 1;
    for (int i = 0; i < MAX_STATES; i++) m->x[i] = 0.0;
    m->x[X_Z_S] = m->r[VR_Z_R];
    m->x[X_Z_U] = m->r[VR_Z_R];
    m->x[X_Z_R_PREV] = m->r[VR_Z_R];
    Params p = read_params(m);
    write_outputs(m, &p);
    return 0;
}

int model_do_step(Instance *m, double h) {
    if (check_params(m)) return 1;
    if (!(h >= 0.0) || !isfinite(h)) {
        snprintf(m->message, MESSAGE_SIZE, "communication step h = %g s must be finite and not negative", h);
        return 1;
    }
    Params p = read_params(m);
    double *s = m->x;
    const double z_r = m->r[VR_Z_R], f_body = m->r[VR_F_BODY], f_wheel = m->r[VR_F_WHEEL];

    /* the staircase's jump: the tyre damper's impulse c_t dz_r [N s] on the wheel, if in contact */
    double dz_r = z_r - s[X_Z_R_PREV];
    if (dz_r != 0.0) {
        double share = 1.0;
        if (p.lift > 0.0 && p.f_static + p.k_t * (z_r - s[X_Z_U]) - p.c_t * s[X_V_U] <= 0.0)
            share = 1.0 - p.lift; /* the tyre is off the post: it cannot pass the impulse */
        s[X_V_U] += share * p.c_t * dz_r / p.m_u;
        s[X_Z_R_PREV] = z_r;
    }

    double n_sub = ceil(h / m->r[VR_H_INT] - 1e-9); /* tolerance: h a multiple of h_int */
    if (n_sub < 1.0) n_sub = 1.0;
    if (n_sub > MAX_SUBSTEPS) {
        snprintf(m->message, MESSAGE_SIZE,
                 "communication step h = %g s needs %.0f internal steps of h_int = %g s (more than %.0f)", h,
                 n_sub, m->r[VR_H_INT], MAX_SUBSTEPS);
        return 1;
    }
    const long n = (long)n_sub;
    const double hs = h / (double)n; /* sub-step [s] */
    double k1[N_CONT], k2[N_CONT], k3[N_CONT], k4[N_CONT], tmp[N_CONT];
    for (long step = 0; step < n && h > 0.0; step++) {
        rhs(&p, s, z_r, f_body, f_wheel, k1);
        for (int i = 0; i < N_CONT; i++) tmp[i] = s[i] + 0.5 * hs * k1[i];
        rhs(&p, tmp, z_r, f_body, f_wheel, k2);
        for (int i = 0; i < N_CONT; i++) tmp[i] = s[i] + 0.5 * hs * k2[i];
        rhs(&p, tmp, z_r, f_body, f_wheel, k3);
        for (int i = 0; i < N_CONT; i++) tmp[i] = s[i] + hs * k3[i];
        rhs(&p, tmp, z_r, f_body, f_wheel, k4);
        for (int i = 0; i < N_CONT; i++) s[i] += hs / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        for (int i = 0; i < N_CONT; i++) {
            if (!isfinite(s[i])) {
                snprintf(m->message, MESSAGE_SIZE,
                         "non-finite state at t = %.9g s (internal step %ld of %ld, h_int = %g s): the "
                         "quarter car diverged; check the parameters (a negative k3 softens the spring "
                         "without bound) or use a smaller h_int",
                         m->time + (double)(step + 1) * hs, step + 1, n, hs);
                return 1;
            }
        }
    }
    write_outputs(m, &p);
    return 0;
}

/* Model exchange: the four continuous states (z_s, v_s, z_u, v_u) and their derivatives at the inputs
 * as the host sets them. The post's velocity is not an input here (FMI 2.0 model exchange has no input
 * derivatives without fmi2SetRealInputDerivatives), so the tyre's damper acts on the wheel's velocity
 * alone, c_t v_u, where the co-simulation step passes the staircase's impulse c_t dz_r as well: the
 * two interfaces agree where the post moves slowly against c_t / k_t (0.25 ms at the nominal values). */
int model_n_states(void) { return N_CONT; }

int model_derivatives(Instance *m, double dx[]) {
    if (check_params(m)) return 1;
    Params p = read_params(m);
    rhs(&p, m->x, m->r[VR_Z_R], m->r[VR_F_BODY], m->r[VR_F_WHEEL], dx);
    write_outputs(m, &p);
    return 0;
}

/* Event indicators of the model-exchange form: where the right-hand side has a kink. z[0] is the
 * tyre's contact force (f_static + the linear tyre force), which lifts the tyre at 0 when tyre_lift
 * is on; z[1] is how far the suspension's compression passes the bump stop's gap, which engages it
 * at 0 when k_bump is on. Off, each is a constant that never crosses zero. */
int model_n_event_indicators(void) { return 2; }

int model_event_indicators(Instance *m, double z[]) {
    if (check_params(m)) return 1;
    Params p = read_params(m);
    const double *s = m->x;
    z[0] = p.lift > 0.0 ? p.f_static + p.k_t * (m->r[VR_Z_R] - s[X_Z_U]) - p.c_t * s[X_V_U] : 1.0;
    z[1] = p.k_bump > 0.0 ? -(s[X_Z_S] - s[X_Z_U]) - p.gap : -1.0;
    return 0;
}
