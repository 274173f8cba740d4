/* Damped least squares for a few poses of a chain, in plain C: SmallRefine's loop (ikdp/small_refine.py).
 *
 * One target's K = 16 poses make arrays of a few hundred numbers, so NumPy's loop spends its time on the
 * fixed cost of its operations (some sixty a step); here a whole refinement, or the network's feature of one
 * denoiser call, is one function. The same arithmetic pose by pose, in float64: each joint's transform a
 * constant plus cos q and sin q times constants, their running product, the rotation error by Shepperd's
 * quaternion of R_target R^T, the Jacobian from the joints' world axes, J^T (J J^T + lambda^2 I)^-1 e by a
 * Cholesky solve (NumPy's is an LU solve: the same to rounding), the limits, and a step that pushes a joint
 * further past its limit compared with the step solved without it (refine.better_of). ikdp/compiled_chain.py
 * builds this file with the system's C compiler on first use; without it NumPy's loop runs.
 *
 * Layouts (float64, row-major, contiguous): joints (N, J), goals (N, 3) or (N, 7) as (x, y, z, w, qx, qy, qz),
 * the chain's constants as FusedChain builds them (ikdp/fused_chain.py).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#if defined(_WIN32)
#define EXPORT __declspec(dllexport)
#else
#define EXPORT
#endif

#define MAX_JOINTS 64 /* a pose's frames live on the stack */
#define PI 3.14159265358979323846 /* np.pi: M_PI is not standard C */

typedef struct {
    int joints;                      /* J */
    int pose_targets;                /* 1: goals (N, 7), a position and a rotation error; 0: (N, 3) */
    const double *fixed;             /* (J, 4, 4): joint j's transform is fixed + cos q cosine + sin q sine */
    const double *cosine;            /* (J, 4, 4) */
    const double *sine;              /* (J, 4, 4) */
    const double *slide;             /* (J, 4, 4), + q prismatic slide; NULL: no prismatic joint */
    const double *prismatic;         /* (J,) 1 for a prismatic joint; NULL with slide */
    const unsigned char *revolute;   /* (J,); NULL: every joint revolute */
    const unsigned char *continuous; /* (J,) wrapped into (-pi, pi] rather than clamped; NULL: none */
    const unsigned char *limited;    /* (J,) not continuous */
    const double *lower;             /* (J,) */
    const double *upper;             /* (J,) */
    const double *end;               /* (4, 4): the end effector in the last joint's frame */
} Chain;

/* c = a b for 4x4 matrices */
static void product(const double *a, const double *b, double *c) {
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 4; k++)
            c[i * 4 + k] = a[i * 4] * b[k] + a[i * 4 + 1] * b[4 + k] + a[i * 4 + 2] * b[8 + k] + a[i * 4 + 3] * b[12 + k];
}

/* each joint's axis frame after its motion (J, 4, 4) and the end effector's (4, 4): FusedChain._frames */
static void frames(const Chain *chain, const double *q, double *world, double *end) {
    double local[16];
    for (int j = 0; j < chain->joints; j++) {
        const double angle = q[j], cosine = cos(angle), sine = sin(angle);
        const double *f = chain->fixed + 16 * j, *c = chain->cosine + 16 * j, *s = chain->sine + 16 * j;
        for (int k = 0; k < 16; k++) local[k] = f[k] + cosine * c[k] + sine * s[k];
        if (chain->slide != NULL) {
            const double along = angle * chain->prismatic[j];
            for (int k = 0; k < 16; k++) local[k] += along * chain->slide[16 * j + k];
        }
        if (j == 0)
            memcpy(world, local, sizeof local);
        else
            product(world + 16 * (j - 1), local, world + 16 * j);
    }
    product(world + 16 * (chain->joints - 1), chain->end, end);
}

/* a unit quaternion (w, x, y, z) as its rotation matrix (3, 3): rotations.quaternion_to_matrix */
static void rotation_of(const double *goal, double *rotation) {
    const double length = sqrt(goal[3] * goal[3] + goal[4] * goal[4] + goal[5] * goal[5] + goal[6] * goal[6]);
    const double w = goal[3] / length, x = goal[4] / length, y = goal[5] / length, z = goal[6] / length;
    rotation[0] = 1 - 2 * (y * y + z * z), rotation[1] = 2 * (x * y - w * z), rotation[2] = 2 * (x * z + w * y);
    rotation[3] = 2 * (x * y + w * z), rotation[4] = 1 - 2 * (x * x + z * z), rotation[5] = 2 * (y * z - w * x);
    rotation[6] = 2 * (x * z - w * y), rotation[7] = 2 * (y * z + w * x), rotation[8] = 1 - 2 * (x * x + y * y);
}

/* the task error (3 or 6): the position miss, then R_target R^T as an axis-angle vector
 * (FusedChain._task_error: Shepperd's candidate with the largest diagonal, w >= 0) */
static void task_error(const Chain *chain, const double *end, const double *goal, const double *rotation,
                       double *error) {
    for (int i = 0; i < 3; i++) error[i] = goal[i] - end[i * 4 + 3];
    if (!chain->pose_targets) return;
    double r[9];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
            r[i * 3 + k] = rotation[i * 3] * end[k * 4] + rotation[i * 3 + 1] * end[k * 4 + 1] +
                           rotation[i * 3 + 2] * end[k * 4 + 2];
    const double candidates[4][4] = {
        {1 + r[0] + r[4] + r[8], r[7] - r[5], r[2] - r[6], r[3] - r[1]},
        {r[7] - r[5], 1 + r[0] - r[4] - r[8], r[3] + r[1], r[2] + r[6]},
        {r[2] - r[6], r[3] + r[1], 1 - r[0] + r[4] - r[8], r[7] + r[5]},
        {r[3] - r[1], r[2] + r[6], r[7] + r[5], 1 - r[0] - r[4] + r[8]},
    };
    int best = 0;
    for (int i = 1; i < 4; i++)
        if (candidates[i][i] > candidates[best][best]) best = i;
    const double *chosen = candidates[best];
    const double length = sqrt(chosen[0] * chosen[0] + chosen[1] * chosen[1] + chosen[2] * chosen[2] +
                               chosen[3] * chosen[3]);
    const double scale = (chosen[0] < 0 ? -1.0 : 1.0) / length;
    const double cosine_half = chosen[0] * scale;
    double vector[3] = {chosen[1] * scale, chosen[2] * scale, chosen[3] * scale};
    const double sine_half = sqrt(vector[0] * vector[0] + vector[1] * vector[1] + vector[2] * vector[2]);
    /* rotations.quaternion_to_axis_angle's small-angle branch */
    const double factor = sine_half < 1e-6 ? 2 / cosine_half : 2 * atan2(sine_half, cosine_half) / sine_half;
    for (int i = 0; i < 3; i++) error[3 + i] = vector[i] * factor;
}

/* (E, J) row-major: FusedChain._jacobian */
static void jacobian_of(const Chain *chain, const double *q, const double *world, const double *end,
                        double *jacobian) {
    const int count = chain->joints;
    for (int j = 0; j < count; j++) {
        const double *frame = world + 16 * j;
        const double axis[3] = {frame[2], frame[6], frame[10]};
        double origin[3] = {frame[3], frame[7], frame[11]};
        const int turns = chain->revolute == NULL || chain->revolute[j];
        if (chain->revolute != NULL) /* a slid joint's frame sits past its origin by q along its axis */
            for (int i = 0; i < 3; i++) origin[i] -= axis[i] * (q[j] * chain->prismatic[j]);
        const double lever[3] = {end[3] - origin[0], end[7] - origin[1], end[11] - origin[2]};
        if (turns) {
            jacobian[0 * count + j] = axis[1] * lever[2] - axis[2] * lever[1];
            jacobian[1 * count + j] = axis[2] * lever[0] - axis[0] * lever[2];
            jacobian[2 * count + j] = axis[0] * lever[1] - axis[1] * lever[0];
        } else { /* a slide moves the end effector along its axis and turns nothing */
            for (int i = 0; i < 3; i++) jacobian[i * count + j] = axis[i];
        }
        if (chain->pose_targets)
            for (int i = 0; i < 3; i++) jacobian[(3 + i) * count + j] = turns ? axis[i] : 0.0;
    }
}

/* J^T (J J^T + lambda^2 I)^-1 e (refine.dls_step), the columns where `skip` is set left out (zero) */
static void dls(int rows, int count, const double *jacobian, const double *error, double damping_squared,
                const unsigned char *skip, double *step) {
    double gram[36], solved[6];
    for (int a = 0; a < rows; a++)
        for (int b = 0; b <= a; b++) {
            double sum = 0;
            for (int j = 0; j < count; j++)
                if (skip == NULL || !skip[j]) sum += jacobian[a * count + j] * jacobian[b * count + j];
            gram[a * rows + b] = sum + (a == b ? damping_squared : 0.0);
        }
    /* Cholesky, lower triangle in place: the damped Gram matrix is symmetric positive definite */
    for (int a = 0; a < rows; a++) {
        for (int b = 0; b <= a; b++) {
            double sum = gram[a * rows + b];
            for (int k = 0; k < b; k++) sum -= gram[a * rows + k] * gram[b * rows + k];
            gram[a * rows + b] = a == b ? sqrt(sum) : sum / gram[b * rows + b];
        }
    }
    for (int a = 0; a < rows; a++) {
        double sum = error[a];
        for (int k = 0; k < a; k++) sum -= gram[a * rows + k] * solved[k];
        solved[a] = sum / gram[a * rows + a];
    }
    for (int a = rows - 1; a >= 0; a--) {
        double sum = solved[a];
        for (int k = a + 1; k < rows; k++) sum -= gram[k * rows + a] * solved[k];
        solved[a] = sum / gram[a * rows + a];
    }
    for (int j = 0; j < count; j++) {
        double sum = 0;
        if (skip == NULL || !skip[j])
            for (int a = 0; a < rows; a++) sum += jacobian[a * count + j] * solved[a];
        step[j] = sum;
    }
}

/* within the limits; a continuous joint wrapped into (-pi, pi] (SmallRefine.normalized) */
static void normalized(const Chain *chain, double *q) {
    for (int j = 0; j < chain->joints; j++) {
        if (chain->continuous != NULL && chain->continuous[j]) {
            const double turn = 2 * PI;
            double wrapped = fmod(q[j] + PI, turn);
            if (wrapped < 0) wrapped += turn;
            if (wrapped >= turn) wrapped -= turn;
            wrapped -= PI;
            q[j] = wrapped == -PI ? PI : wrapped;
        } else {
            q[j] = fmin(fmax(q[j], chain->lower[j]), chain->upper[j]);
        }
    }
}

static double length_of(const double *vector, int size) {
    double sum = 0;
    for (int i = 0; i < size; i++) sum += vector[i] * vector[i];
    return sqrt(sum);
}

/* the task error's norm at q: what the refinement minimises, which compares a blocked pose's two candidates */
static double miss(const Chain *chain, const double *q, const double *goal, const double *rotation, double *world) {
    double end[16], error[6];
    frames(chain, q, world, end);
    task_error(chain, end, goal, rotation, error);
    return length_of(error, chain->pose_targets ? 6 : 3);
}

/* The task error (N, E) and the damped least-squares step (N, J) at each pose: SmallRefine.error_and_step.
 * 0, or -1 when the chain has more than MAX_JOINTS joints. */
EXPORT int ikdp_chain_error_and_step(const Chain *chain, int rows, const double *joints, const double *goals,
                                     double damping_squared, double *errors, double *steps) {
    const int count = chain->joints, size = chain->pose_targets ? 6 : 3, width = chain->pose_targets ? 7 : 3;
    if (count > MAX_JOINTS || count < 1) return -1;
    double world[16 * MAX_JOINTS], end[16], rotation[9], jacobian[6 * MAX_JOINTS];
    for (int n = 0; n < rows; n++) {
        const double *q = joints + n * count, *goal = goals + n * width;
        if (chain->pose_targets) rotation_of(goal, rotation);
        frames(chain, q, world, end);
        task_error(chain, end, goal, rotation, errors + n * size);
        jacobian_of(chain, q, world, end, jacobian);
        dls(size, count, jacobian, errors + n * size, damping_squared, NULL, steps + n * count);
    }
    return 0;
}

/* SmallRefine.refine_scored: `steps` damped least-squares steps of joints (N, J), in place, toward goals.
 *
 * position_limit, rotation_limit: the error's parts clamped to these norms (refine.clamp_task_error).
 * per_target > 0: stop before a step once each target, per_target consecutive rows, has a pose whose position
 * error is below position_tolerance and (pose targets) rotation angle below rotation_tolerance.
 * scored: the errors written to scores (3, N) float32: the refined poses' position errors and rotation angles
 * (the norms of the error's parts), then the given poses' position errors; after all the steps (not stopped)
 * measured on the poses rounded to float32 where round_float32, as the caller returns them.
 * 0, or -1 when the chain has more than MAX_JOINTS joints or memory ran out. */
EXPORT int ikdp_chain_refine(const Chain *chain, int rows, double *joints, const double *goals, int steps,
                             double damping_squared, double position_limit, double rotation_limit, int per_target,
                             double position_tolerance, double rotation_tolerance, int scored, int round_float32,
                             float *scores) {
    const int count = chain->joints, parts = chain->pose_targets ? 2 : 1, size = 3 * parts;
    const int width = chain->pose_targets ? 7 : 3;
    if (count > MAX_JOINTS || count < 1) return -1;
    if (rows < 1) return 0; /* nothing to refine (and malloc(0) may answer NULL) */
    double *rotations = malloc(sizeof(double) * (size_t)rows * 9);
    double *norms = malloc(sizeof(double) * (size_t)rows * 2);
    double *errors = malloc(sizeof(double) * (size_t)rows * 6);
    double *worlds = malloc(sizeof(double) * (size_t)rows * 16 * (count + 1)); /* the frames, then the end's */
    if (rotations == NULL || norms == NULL || errors == NULL || worlds == NULL) {
        free(rotations), free(norms), free(errors), free(worlds);
        return -1;
    }
    const double limits[2] = {position_limit, rotation_limit};
    for (int n = 0; n < rows && chain->pose_targets; n++) rotation_of(goals + n * width, rotations + n * 9);
    for (int index = 0; index <= steps; index++) {
        if (index == steps) {
            if (!scored) break;
            if (round_float32)
                for (int i = 0; i < rows * count; i++) joints[i] = (double)(float)joints[i];
        }
        for (int n = 0; n < rows; n++) {
            double *world = worlds + (size_t)n * 16 * (count + 1), *end = world + 16 * count;
            frames(chain, joints + n * count, world, end);
            task_error(chain, end, goals + n * width, rotations + n * 9, errors + n * 6);
            for (int p = 0; p < parts; p++) norms[n * 2 + p] = length_of(errors + n * 6 + 3 * p, 3);
            if (index == 0 && scored) scores[2 * rows + n] = (float)norms[n * 2];
        }
        if (index == steps) break;
        if (per_target > 0) { /* every target reached: no more steps */
            int all = 1;
            for (int first = 0; first < rows && all; first += per_target) {
                int any = 0;
                for (int n = first; n < first + per_target && n < rows && !any; n++)
                    any = norms[n * 2] < position_tolerance && (parts == 1 || norms[n * 2 + 1] < rotation_tolerance);
                all = any;
            }
            if (all) break;
        }
        for (int n = 0; n < rows; n++) {
            double *q = joints + n * count, *world = worlds + (size_t)n * 16 * (count + 1), *end = world + 16 * count;
            const double *goal = goals + n * width, *rotation = rotations + n * 9;
            double jacobian[6 * MAX_JOINTS], error[6], step[MAX_JOINTS], moved[MAX_JOINTS];
            jacobian_of(chain, q, world, end, jacobian);
            for (int p = 0; p < parts; p++) { /* each part clamped to its limit's norm */
                const double norm = norms[n * 2 + p], factor = limits[p] / fmax(norm, limits[p]);
                for (int i = 0; i < 3; i++) error[3 * p + i] = errors[n * 6 + 3 * p + i] * factor;
            }
            dls(size, count, jacobian, error, damping_squared, NULL, step);
            unsigned char blocked[MAX_JOINTS];
            int any_blocked = 0;
            for (int j = 0; j < count; j++) {
                moved[j] = q[j] + step[j];
                blocked[j] = chain->limited[j] &&
                             ((q[j] <= chain->lower[j] && step[j] < 0) || (q[j] >= chain->upper[j] && step[j] > 0));
                any_blocked |= blocked[j];
            }
            normalized(chain, moved);
            if (any_blocked) { /* the step solved without the blocked joints, kept where it misses by less */
                double held[MAX_JOINTS];
                dls(size, count, jacobian, error, damping_squared, blocked, step);
                for (int j = 0; j < count; j++) held[j] = q[j] + step[j];
                normalized(chain, held);
                if (miss(chain, held, goal, rotation, world) < miss(chain, moved, goal, rotation, world))
                    memcpy(moved, held, sizeof(double) * count);
            }
            memcpy(q, moved, sizeof(double) * count);
        }
    }
    if (scored)
        for (int n = 0; n < rows; n++) {
            scores[n] = (float)norms[n * 2];
            scores[rows + n] = parts > 1 ? (float)norms[n * 2 + 1] : 0.0f;
        }
    free(rotations), free(norms), free(errors), free(worlds);
    return 0;
}
