/*
 * The reference plant of docs/MODEL.md (sections 1 and 2) as the model of an FMI 2.0
 * co-simulation FMU: an induction motor (per unit, stationary alpha-beta frame) driving a mass
 * through a clutch with backlash, a drive wheel and a resilient element, the mass held by an
 * absorber; and the backlash test: at rest at t = 0, switched on direct-on-line, armed at the
 * first contact of the clutch, switched off (electromagnetic torque zero) at the event t_e, the
 * first instant after that at which the clutch re-enters its backlash zone.
 *
 * The equations, the integrator and the event location mirror the project's native simulator
 * (engine/simulation/_kernel.py: rhs, rk4_step, zone, hybrid_step, advance) with only the
 * reference model's terms, except the additive unknown inputs d_* (FMU inputs, held over a
 * communication step) and three catalogue effects neutral at their defaults (tau_C1, b1,
 * load_inertia_factor).
 *
 * Integration: classical RK4 with fixed sub-steps no longer than h_int [s]: a communication step
 * of h is cut into ceil(h / h_int) equal sub-steps, and a sub-step that changes the clutch's mode
 * (enters or leaves the backlash zone, starts or stops pushing) is cut at the change, located by
 * bisection on the sub-step to 1e-12 s: RK4 then only integrates a smooth right-hand side, and the
 * event t_e (a mode change into the zone) is located to far below a microsecond.
 *
 * No global mutable state: every value lives in the Instance (reals by value reference in m->r,
 * the state in m->x), so several instances may run at once on different threads.
 *
 * C99. Contract: ../../../c/model.h (the framework fmi2_cs.c implements the fmi2 functions).
 */
#include <math.h>
#include <stdio.h>

#include "model.h"

/* ---- value references (indices into m->r; the order of modelDescription.xml) ---------------- */
enum {
    /* parameters */
    VR_K = 0,          /* backlash K [m]: the clutch's dead zone has half-width b = K / r [rad] */
    VR_J1,             /* motor-side inertia [kg m^2]; T_1 = J1 * 0.86 / 0.87 [s] */
    VR_C,              /* absorber's apparent viscosity c [pu torque / pu speed] */
    VR_C1,             /* absorber's discontinuity at zero speed c_1 [pu torque] */
    VR_R_S,            /* stator resistance [pu] */
    VR_R_R,            /* rotor resistance [pu] */
    VR_X_S,            /* total stator reactance [pu] */
    VR_X_R,            /* total rotor reactance [pu] */
    VR_X_M,            /* magnetising reactance [pu] */
    VR_U,              /* supply voltage amplitude [pu] */
    VR_F,              /* supply frequency [pu of 50 Hz] */
    VR_P,              /* pole pairs [-] */
    VR_J2,             /* drive-wheel inertia [kg m^2]; T_2 = J2 * 0.86 / 0.87 [s] */
    VR_T3,             /* mechanical time constant of the mass m2 referred to the motor shaft [s] */
    VR_RADIUS,         /* drive-wheel radius r [m] */
    VR_K12,            /* clutch contact stiffness [pu torque / rad] */
    VR_D12,            /* clutch contact damping [pu torque / pu speed] */
    VR_K2,             /* resilient element stiffness [pu torque / rad] */
    VR_D2,             /* resilient element damping [pu torque / pu speed] */
    VR_H_INT,          /* largest internal RK4 step [s] */
    VR_TAU_C1,         /* Coulomb friction torque on J1, tau_C1 tanh(w_1 / 1e-3) [pu] */
    VR_B1,             /* viscous friction on J1, b1 w_1 [pu torque / pu speed] */
    VR_LOAD_INERTIA,   /* factor on T3 [-] */
    /* inputs (held over a communication step) */
    VR_D_SUPPLY,       /* relative deviation of the supply amplitude: u -> u (1 + d_supply) [-] */
    VR_D_EL,           /* additive electromagnetic torque, in m_el and on J1 [pu] */
    VR_D_SHAFT,        /* torque on J1 [pu] */
    VR_D_WHEEL,        /* torque on J2 [pu] */
    VR_D_LOAD,         /* torque on the mass m2 [pu] */
    /* outputs */
    VR_A1,             /* r * Omega_b * dw_1/dt [m/s^2] */
    VR_M_EL,           /* electromagnetic torque [pu] */
    VR_OMEGA1,         /* Omega_b * w_1 [rad/s] */
    VR_A2,             /* r * Omega_b * dw_3/dt [m/s^2] */
    VR_V2,             /* r * Omega_b * w_3 [m/s] */
    VR_T_EVENT,        /* the located event t_e [s], -1 before it */
    VR_MOTOR_ON,       /* 1 before the event, 0 from it on [-] */
    N_REALS
};

/* ---- layout of m->x ------------------------------------------------------------------------- */
enum {
    /* 0..3 psi_s_alpha, psi_s_beta, psi_r_alpha, psi_r_beta [pu]; 4..6 w_1, w_2, w_3 [pu speed];
     * 7..9 theta_1, theta_2, theta_3 [mechanical rad]: the kernel's state y[0:10] */
    N_Y = 10,
    X_ARMED = N_Y,     /* 1 once the clutch was in contact (the test is armed) */
    X_MOTOR_ON,        /* 1 before the event, 0 from it on */
    X_T_EVENT,         /* the event instant [s, FMU time], -1 before it */
    X_T_ON,            /* the switch-on instant [s, FMU time]: the experiment's start */
    N_X
};

/* ---- constants of MODEL.md -------------------------------------------------------------------- */
static const double W_B_RATED = 2.0 * 3.14159265358979323846 * 50.0; /* electrical base w_b [rad/s] */
static const double TM_PER_J = 0.86 / 0.87;  /* T_i = J_i * TM_PER_J [s / (kg m^2)] */
static const double W_SMOOTH = 1e-3;         /* smoothing of the sign functions [pu speed] */
static const double T_EVENT_MAX = 1.0;       /* no event within this time after switch-on: error [s] */
static const double BISECTION_TOL = 1e-12;   /* width of the bracket of a mode change [s] */
static const double SPAN_EPS = 1e-15;        /* a rest of a step shorter than this is done [s] */

/* The parameters and inputs in the form the right-hand side uses (from m->r, once per step). */
typedef struct {
    double r_s, r_r, x_s, x_r, x_m; /* [pu] */
    double det;                     /* x_s x_r - x_m^2 [pu^2] */
    double u, f;                    /* supply amplitude [pu], frequency [pu] */
    double w_b, omega_b;            /* base values [rad/s]: electrical, mechanical (w_b / p) */
    double T1, T2, T3;              /* mechanical time constants [s] */
    double b;                       /* half-width of the backlash zone [rad] */
    double k12, d12, k2, d2, c, c1; /* [pu / rad], [pu / pu speed], [pu] */
    double tau_c1, b1;              /* motor friction: Coulomb [pu], viscous [pu / pu speed] */
    double radius;                  /* [m] */
    double d_supply, d_el, d_shaft, d_wheel, d_load; /* unknown inputs [-], [pu] */
} Params;

static void load_params(const Instance *m, Params *P)
{
    const double *r = m->r;
    P->r_s = r[VR_R_S];
    P->r_r = r[VR_R_R];
    P->x_s = r[VR_X_S];
    P->x_r = r[VR_X_R];
    P->x_m = r[VR_X_M];
    P->det = P->x_s * P->x_r - P->x_m * P->x_m;
    P->u = r[VR_U];
    P->f = r[VR_F];
    P->w_b = W_B_RATED;
    P->omega_b = W_B_RATED / r[VR_P];
    P->T1 = r[VR_J1] * TM_PER_J;
    P->T2 = r[VR_J2] * TM_PER_J;
    P->T3 = r[VR_T3] * r[VR_LOAD_INERTIA];
    P->b = r[VR_K] / r[VR_RADIUS];
    P->k12 = r[VR_K12];
    P->d12 = r[VR_D12];
    P->k2 = r[VR_K2];
    P->d2 = r[VR_D2];
    P->c = r[VR_C];
    P->c1 = r[VR_C1];
    P->tau_c1 = r[VR_TAU_C1];
    P->b1 = r[VR_B1];
    P->radius = r[VR_RADIUS];
    P->d_supply = r[VR_D_SUPPLY];
    P->d_el = r[VR_D_EL];
    P->d_shaft = r[VR_D_SHAFT];
    P->d_wheel = r[VR_D_WHEEL];
    P->d_load = r[VR_D_LOAD];
}

/* The clutch's contact torque before its clip, k12 (d -+ b) + d12 dw [pu], at |d| > b. */
static double contact_push(const Params *P, double d, double dw)
{
    double x = d > P->b ? d - P->b : d + P->b; /* penetration beyond the zone's edge [rad] */
    return P->k12 * x + P->d12 * dw;
}

/* Mode of the clutch at state y: 0 inside the zone (|d| <= b); +1 / -1 in contact and pushing;
 * +2 / -2 penetrated with the contact force clipped to zero (a contact pushes, never pulls). */
static int zone(const Params *P, const double *y)
{
    double d = y[7] - y[8];
    double dw;
    if (-P->b <= d && d <= P->b)
        return 0;
    dw = y[4] - y[5];
    if (d > P->b)
        return contact_push(P, d, dw) > 0.0 ? 1 : 2;
    return contact_push(P, d, dw) < 0.0 ? -1 : -2;
}

/* Right-hand side dy/dt at (t, y) and, if ch is not NULL, the five channels
 * [a1 m/s^2, m_el pu, omega1 rad/s, a2 m/s^2, v2 m/s]. t is the time since switch-on [s]. */
static void rhs(const Params *P, double t, const double *y, int motor_on, double *dy, double *ch)
{
    double psa = y[0], psb = y[1], pra = y[2], prb = y[3];
    double w1 = y[4], w2 = y[5], w3 = y[6];
    double m_el, d, dw, m_c, m_s, m_a, m_f, m_1, m_2, m_3;
    double dw1, dw2, dw3;

    if (motor_on) {
        double isa = (P->x_r * psa - P->x_m * pra) / P->det; /* stator current [pu] */
        double isb = (P->x_r * psb - P->x_m * prb) / P->det;
        double ira = (P->x_s * pra - P->x_m * psa) / P->det; /* rotor current [pu] */
        double irb = (P->x_s * prb - P->x_m * psb) / P->det;
        double ang = P->f * P->w_b * t;          /* supply phase [rad] */
        double u = P->u * (1.0 + P->d_supply);   /* supply amplitude [pu] */
        double usa = u * cos(ang);
        double usb = u * sin(ang);
        dy[0] = P->w_b * (usa - P->r_s * isa);
        dy[1] = P->w_b * (usb - P->r_s * isb);
        dy[2] = P->w_b * (-P->r_r * ira - w1 * prb);
        dy[3] = P->w_b * (-P->r_r * irb + w1 * pra);
        m_el = psa * isb - psb * isa;
    } else { /* switched off: no torque, the (then unobservable) fluxes frozen, as in the kernel */
        dy[0] = dy[1] = dy[2] = dy[3] = 0.0;
        m_el = 0.0;
    }
    m_el += P->d_el;

    /* clutch with backlash: a contact can push, never pull */
    d = y[7] - y[8];
    dw = w1 - w2;
    if (d > P->b) {
        double push = contact_push(P, d, dw);
        m_c = push > 0.0 ? push : 0.0;
    } else if (d < -P->b) {
        double push = contact_push(P, d, dw);
        m_c = push < 0.0 ? push : 0.0;
    } else {
        m_c = 0.0;
    }
    m_s = P->k2 * (y[8] - y[9]) + P->d2 * (w2 - w3);   /* resilient element [pu] */
    m_a = P->c * w3 + P->c1 * tanh(w3 / W_SMOOTH);     /* absorber [pu] */
    m_f = P->b1 * w1;                                  /* motor friction [pu] */
    if (P->tau_c1 != 0.0)
        m_f += P->tau_c1 * tanh(w1 / W_SMOOTH);
    m_1 = m_el - m_c - m_f + P->d_shaft;
    m_2 = m_c - m_s + P->d_wheel;
    m_3 = m_s - m_a + P->d_load;
    dw1 = m_1 / P->T1;
    dw2 = m_2 / P->T2;
    dw3 = m_3 / P->T3;
    dy[4] = dw1;
    dy[5] = dw2;
    dy[6] = dw3;
    dy[7] = P->omega_b * w1;
    dy[8] = P->omega_b * w2;
    dy[9] = P->omega_b * w3;
    if (ch) {
        ch[0] = P->radius * P->omega_b * dw1;
        ch[1] = m_el;
        ch[2] = P->omega_b * w1;
        ch[3] = P->radius * P->omega_b * dw3;
        ch[4] = P->radius * P->omega_b * w3;
    }
}

/* One classical RK4 step of h [s] from (t, y) into out. */
static void rk4_step(const Params *P, double t, const double *y, double h, int motor_on, double *out)
{
    double k1[N_Y], k2[N_Y], k3[N_Y], k4[N_Y], tmp[N_Y];
    double hh = 0.5 * h, h6 = h / 6.0;
    int i;
    rhs(P, t, y, motor_on, k1, NULL);
    for (i = 0; i < N_Y; i++)
        tmp[i] = y[i] + hh * k1[i];
    rhs(P, t + hh, tmp, motor_on, k2, NULL);
    for (i = 0; i < N_Y; i++)
        tmp[i] = y[i] + hh * k2[i];
    rhs(P, t + hh, tmp, motor_on, k3, NULL);
    for (i = 0; i < N_Y; i++)
        tmp[i] = y[i] + h * k3[i];
    rhs(P, t + h, tmp, motor_on, k4, NULL);
    for (i = 0; i < N_Y; i++)
        out[i] = y[i] + h6 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

/* One RK4 step of at most h [s] from (t, y), mode z0, that stops at a change of the clutch's mode
 * (bisection on the step to BISECTION_TOL; the step ends on the far side of the change).
 * Writes the new state to out; returns the step taken [s]; *crossed = whether it ended at a mode
 * change, *z1 = the mode at its end. */
static double hybrid_step(const Params *P, double t, const double *y, double h, int motor_on, int z0,
                          double *out, int *crossed, int *z1)
{
    double lo = 0.0, hi = h;
    rk4_step(P, t, y, h, motor_on, out);
    *z1 = zone(P, out);
    if (*z1 == z0) {
        *crossed = 0;
        return h;
    }
    while (hi - lo > BISECTION_TOL) {
        double h_try = 0.5 * (lo + hi);
        double trial[N_Y];
        rk4_step(P, t, y, h_try, motor_on, trial);
        if (zone(P, trial) == z0)
            lo = h_try;
        else
            hi = h_try;
    }
    rk4_step(P, t, y, hi, motor_on, out);
    *z1 = zone(P, out);
    *crossed = 1;
    return hi;
}

static int all_finite(const double *y)
{
    int i;
    for (i = 0; i < N_Y; i++)
        if (!isfinite(y[i]))
            return 0;
    /* the kernel's test of an absurd state: a speed or clutch deflection beyond 1e6 */
    return fabs(y[4]) < 1e6 && fabs(y[7] - y[8]) < 1e6;
}

/* Write the outputs at the state in m->x, time since switch-on t [s]. */
static void write_outputs(Instance *m, const Params *P, double t)
{
    double dy[N_Y], ch[5];
    int motor_on = m->x[X_MOTOR_ON] != 0.0;
    rhs(P, t, m->x, motor_on, dy, ch);
    m->r[VR_A1] = ch[0];
    m->r[VR_M_EL] = ch[1];
    m->r[VR_OMEGA1] = ch[2];
    m->r[VR_A2] = ch[3];
    m->r[VR_V2] = ch[4];
    m->r[VR_T_EVENT] = m->x[X_T_EVENT];
    m->r[VR_MOTOR_ON] = motor_on ? 1.0 : 0.0;
}

/* Check the parameters; 0 or non-zero with m->message set. */
static int check_params(Instance *m)
{
    static const struct {
        int vr;
        const char *name;
    } positive[] = {
        {VR_K, "K"}, {VR_J1, "J1"}, {VR_J2, "J2"}, {VR_T3, "T3"}, {VR_RADIUS, "r"},
        {VR_P, "p"}, {VR_H_INT, "h_int"}, {VR_LOAD_INERTIA, "load_inertia_factor"},
        {VR_X_S, "x_s"}, {VR_X_R, "x_r"}, {VR_X_M, "x_m"},
    };
    int i;
    for (i = 0; i < VR_A1; i++) {
        if (!isfinite(m->r[i])) {
            snprintf(m->message, MESSAGE_SIZE, "parameter or input with value reference %d is not finite (%g)",
                     i, m->r[i]);
            return 1;
        }
    }
    for (i = 0; i < (int)(sizeof positive / sizeof positive[0]); i++) {
        if (!(m->r[positive[i].vr] > 0.0)) {
            snprintf(m->message, MESSAGE_SIZE, "parameter %s must be positive, got %g", positive[i].name,
                     m->r[positive[i].vr]);
            return 1;
        }
    }
    if (!(m->r[VR_X_S] * m->r[VR_X_R] - m->r[VR_X_M] * m->r[VR_X_M] > 0.0)) {
        snprintf(m->message, MESSAGE_SIZE, "x_s * x_r - x_m^2 must be positive (leakage), got x_s = %g, x_r = %g, x_m = %g",
                 m->r[VR_X_S], m->r[VR_X_R], m->r[VR_X_M]);
        return 1;
    }
    if (m->r[VR_H_INT] < 1e-8 || m->r[VR_H_INT] > 1e-3) {
        snprintf(m->message, MESSAGE_SIZE,
                 "h_int must lie in [1e-8, 1e-3] s (RK4 on the 50 Hz supply and the 60 Hz contact mode), got %g s",
                 m->r[VR_H_INT]);
        return 1;
    }
    return 0;
}

/* ---- the contract of model.h ------------------------------------------------------------------ */

int model_n_reals(void)
{
    return N_REALS;
}

void model_start_values(Instance *m)
{
    double *r = m->r;
    int i;
    for (i = 0; i < N_REALS; i++)
        r[i] = 0.0;
    r[VR_K] = 0.005;
    r[VR_J1] = 0.87;
    r[VR_C] = 1.0;
    r[VR_C1] = 0.2;
    r[VR_R_S] = 0.059;
    r[VR_R_R] = 0.048;
    r[VR_X_S] = 1.92;
    r[VR_X_R] = 1.92;
    r[VR_X_M] = 1.82;
    r[VR_U] = 1.0;
    r[VR_F] = 1.0;
    r[VR_P] = 2.0;
    r[VR_J2] = 0.348;
    r[VR_T3] = 0.30;
    r[VR_RADIUS] = 0.1;
    r[VR_K12] = 222.0;
    r[VR_D12] = 0.5;
    r[VR_K2] = 9.0;
    r[VR_D2] = 0.02;
    r[VR_H_INT] = 5e-5;
    r[VR_TAU_C1] = 0.0;
    r[VR_B1] = 0.0;
    r[VR_LOAD_INERTIA] = 1.0;
    /* inputs 0; outputs as at rest */
    r[VR_T_EVENT] = -1.0;
    r[VR_MOTOR_ON] = 1.0;
}

int model_initialize(Instance *m)
{
    Params P;
    int i;
    if (check_params(m))
        return 1;
    for (i = 0; i < N_Y; i++) /* at rest, fluxes zero, the clutch in the middle of its zone */
        m->x[i] = 0.0;
    m->x[X_ARMED] = 0.0;
    m->x[X_MOTOR_ON] = 1.0; /* switched on direct-on-line at the experiment's start */
    m->x[X_T_EVENT] = -1.0;
    m->x[X_T_ON] = m->time;
    load_params(m, &P);
    write_outputs(m, &P, 0.0);
    return 0;
}

int model_do_step(Instance *m, double h)
{
    Params P;
    double *y = m->x;
    double t_on = m->x[X_T_ON];
    double t = m->time - t_on; /* time since switch-on [s] */
    double t_end = t + h;
    double h_int;
    int motor_on = m->x[X_MOTOR_ON] != 0.0;
    int armed = m->x[X_ARMED] != 0.0;
    int z;

    if (!(h >= 0.0) || !isfinite(h)) {
        snprintf(m->message, MESSAGE_SIZE, "communication step must be finite and >= 0, got %g s", h);
        return 1;
    }
    if (check_params(m))
        return 1;
    load_params(m, &P);
    h_int = m->r[VR_H_INT];
    z = zone(&P, y);
    while (t_end - t > SPAN_EPS) {
        double span = t_end - t;
        double n = ceil(span / h_int - 1e-9); /* equal sub-steps no longer than h_int */
        double hs = span / (n > 1.0 ? n : 1.0);
        double out[N_Y];
        int crossed, z1, i;
        double taken = hybrid_step(&P, t, y, hs, motor_on, z, out, &crossed, &z1);
        t = (!crossed && n <= 1.0) ? t_end : t + taken;
        for (i = 0; i < N_Y; i++)
            y[i] = out[i];
        z = z1;
        if (!all_finite(y)) {
            snprintf(m->message, MESSAGE_SIZE,
                     "the integration diverged (non-finite or absurd state) at t = %.9g s; check the parameters",
                     t + t_on);
            return 1;
        }
        if (motor_on) {
            if (z != 0) {
                armed = 1; /* in contact (or penetrated): the test is armed */
            } else if (armed && crossed) {
                /* the event: the clutch re-enters its zone; from here on the motor is off */
                motor_on = 0;
                m->x[X_T_EVENT] = t + t_on;
            }
            if (motor_on && t >= T_EVENT_MAX) {
                snprintf(m->message, MESSAGE_SIZE,
                         "no backlash event (re-entry into the zone after first contact) within %g s of "
                         "simulated time after switch-on",
                         T_EVENT_MAX);
                m->x[X_ARMED] = armed;
                return 1;
            }
        }
    }
    m->x[X_ARMED] = armed ? 1.0 : 0.0;
    m->x[X_MOTOR_ON] = motor_on ? 1.0 : 0.0;
    write_outputs(m, &P, t_end);
    return 0;
}
