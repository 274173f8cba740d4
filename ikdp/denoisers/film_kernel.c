/* One call of the planar FiLM denoiser (cossin representation) on M rows, in plain C.
 *
 * The same arithmetic as FiLMWorkspace.denoise in film.py, written as loops: a solve of one
 * target calls the denoiser 80 times on 16 rows, where each torch op's fixed cost (a few
 * microseconds) outweighs its arithmetic; here a whole call is one function with no
 * allocation. ikdp/denoisers/film_compiled.py builds this file with the system's C compiler
 * on first use and falls back to the torch path when it cannot.
 *
 * Layouts (all float32, row-major, contiguous unless a stride is given):
 *   x        (M, 2N)      the noisy sample: each link's (cos, sin), not necessarily unit
 *   target   (M / G, 2)   rows apart by target_stride floats (0: one target for all rows)
 *   film     (M / G, B+1, 2, H) rows apart by film_stride floats (0: one condition for all rows);
 *            [b][0] is block b's scale, [b][1] its shift, [B][0][:F] the feature scales
 *   w_in     (F, H)       the input layer's weight transposed, F = 2N + 2 + N
 *   w_blocks (B, H, H)    each block's weight transposed
 *   w_out    (H, N)       the output layer's weight transposed
 *            G = rows_per_condition consecutive rows of x share a target and a condition (the K
 *            samples of one target), so they are never copied K times
 *   scratch  min(M, CHUNK) * (F + 3H + N + 2N) floats
 *   clean    (M, 2N)      the estimate of x_0: each unit direction turned by the network's angle
 */
#include <math.h>
#include <stddef.h>

#define TILE 4   /* rows that share each weight loaded */
#define CHUNK 32 /* rows taken through all layers at once: their activations fit in the L1/L2 cache */

/* Standard C99 throughout, so that any C compiler builds it (GCC, Clang, MSVC; x86, ARM). The one
 * extension, GCC/Clang vector types, is used where the compiler offers it and is never required:
 * elsewhere (or with -DIKDP_PLAIN_C) the same sums run as plain loops, which compilers vectorise less well. */
#if defined(_MSC_VER) && !defined(__clang__)
#define RESTRICT __restrict /* MSVC's C has `restrict` only under /std:c11 */
#else
#define RESTRICT restrict
#endif

#if defined(_WIN32)
#define EXPORT __declspec(dllexport) /* a DLL exports only what it is told to */
#else
#define EXPORT
#endif

#if defined(__GNUC__) && !defined(IKDP_PLAIN_C)
#define VECTORS 1
/* One vector is one register: 8 floats with AVX, else 4 (SSE2 on every x86-64, NEON on ARM). A 32-byte
 * vector without AVX is emulated through memory and runs 20 times slower than the 16-byte one. */
#if defined(__AVX__)
#define LANES 8
#else
#define LANES 4
#endif
typedef float vec __attribute__((vector_size(LANES * sizeof(float))));
/* memcpy, not a cast: the weights and rows are only float-aligned. Macros, not functions: a vector passed
 * by value is an ABI question the compiler warns about */
#define LOAD(vector, pointer) __builtin_memcpy(&(vector), (pointer), sizeof(vec))
#define STORE(pointer, vector) __builtin_memcpy((pointer), &(vector), sizeof(vec))
/* keep the weights in registers: folded into each multiply-add they were loaded 4 times. Only where a
 * vector fits one register of the named class (SSE's "x" holds 16 bytes, 32 with AVX; NEON's "w" 16) */
#if defined(__SSE__)
#define KEEP_IN_REGISTERS(a, b) __asm__("" : "+x"(a), "+x"(b))
#elif defined(__aarch64__)
#define KEEP_IN_REGISTERS(a, b) __asm__("" : "+w"(a), "+w"(b))
#else
#define KEEP_IN_REGISTERS(a, b) ((void)0)
#endif
#endif

/* v * sigmoid(v); the exponent is clamped so it stays finite (the build assumes finite math to vectorise expf) */
static float silu(float v) { return v / (1.0f + expf(fminf(-v, 80.0f))); }

/* out[r][j] = bias[j] + sum_k in[r][k] * weight[k][j], for `rows` rows of `k_count` inputs.
 * Four rows by sixteen outputs are summed in registers over all k, so each weight is loaded
 * once per four rows and nothing is stored until the sums are done (the layers are 128 wide). */
static void affine(int rows, const float *RESTRICT in, int k_count, const float *RESTRICT weight,
                   const float *RESTRICT bias, int n, float *RESTRICT out) {
    int r = 0;
#ifdef VECTORS
    if (n % (2 * LANES) == 0) {
        for (; r + TILE <= rows; r += TILE) {
            const float *i0 = in + (size_t)r * k_count, *i1 = i0 + k_count, *i2 = i1 + k_count, *i3 = i2 + k_count;
            for (int j = 0; j < n; j += 2 * LANES) {
                vec bias_low, bias_high;
                LOAD(bias_low, bias + j);
                LOAD(bias_high, bias + j + LANES);
                vec a0 = bias_low, b0 = bias_high, a1 = bias_low, b1 = bias_high;
                vec a2 = bias_low, b2 = bias_high, a3 = bias_low, b3 = bias_high;
                for (int k = 0; k < k_count; k++) {
                    vec low, high;
                    LOAD(low, weight + (size_t)k * n + j);
                    LOAD(high, weight + (size_t)k * n + j + LANES);
                    KEEP_IN_REGISTERS(low, high);
                    a0 += i0[k] * low;
                    b0 += i0[k] * high;
                    a1 += i1[k] * low;
                    b1 += i1[k] * high;
                    a2 += i2[k] * low;
                    b2 += i2[k] * high;
                    a3 += i3[k] * low;
                    b3 += i3[k] * high;
                }
                float *o = out + (size_t)r * n + j;
                STORE(o, a0), STORE(o + LANES, b0), o += n;
                STORE(o, a1), STORE(o + LANES, b1), o += n;
                STORE(o, a2), STORE(o + LANES, b2), o += n;
                STORE(o, a3), STORE(o + LANES, b3);
            }
        }
    }
#endif
    for (; r < rows; r++) {
        float *RESTRICT o = out + (size_t)r * n;
        const float *i = in + (size_t)r * k_count;
        for (int j = 0; j < n; j++) o[j] = bias[j];
        for (int k = 0; k < k_count; k++) {
            const float a = i[k];
            const float *RESTRICT w = weight + (size_t)k * n;
            for (int j = 0; j < n; j++) o[j] += a * w[j];
        }
    }
}

/* features of one row: [x, miss, DLS step] times the feature scales; also the unit directions */
static void row_features(int links, const float *x, const float *target, const float *lengths,
                         float damping_squared, const float *feature_scale, float *unit, float *features) {
    const int dim = 2 * links;
    float tip_x = 0.0f, tip_y = 0.0f, xx = 0.0f, xy = 0.0f, yy = 0.0f;
    for (int n = 0; n < links; n++) {
        float cx = x[2 * n], cy = x[2 * n + 1];
        float norm = sqrtf(cx * cx + cy * cy);
        if (norm < 1e-12f) norm = 1e-12f;
        unit[2 * n] = cx / norm;
        unit[2 * n + 1] = cy / norm;
        float bx = unit[2 * n] * lengths[n], by = unit[2 * n + 1] * lengths[n];
        tip_x += bx;
        tip_y += by;
        xx += bx * bx;
        xy += bx * by;
        yy += by * by;
    }
    /* refine.planar_dls_step: adj(J J^T + lambda^2 I) = sum_n b_n b_n^T + lambda^2 I */
    const float miss_x = target[0] - tip_x, miss_y = target[1] - tip_y;
    const float a = xx + damping_squared, d = yy + damping_squared;
    const float determinant = a * d - xy * xy;
    const float solved_x = (a * miss_x + xy * miss_y) / determinant;
    const float solved_y = (xy * miss_x + d * miss_y) / determinant;
    for (int i = 0; i < dim; i++) features[i] = x[i] * feature_scale[i];
    features[dim] = miss_x * feature_scale[dim];
    features[dim + 1] = miss_y * feature_scale[dim + 1];
    for (int n = 0; n < links; n++) {
        float bx = unit[2 * n] * lengths[n], by = unit[2 * n + 1] * lengths[n];
        /* bone n's Jacobian column is the bone turned by 90 degrees: (-b_y, b_x) */
        features[dim + 2 + n] = (-by * solved_x + bx * solved_y) * feature_scale[dim + 2 + n];
    }
}

/* What stays the same from call to call, set once by the caller (film_compiled.py mirrors it) */
typedef struct {
    int rows, links, hidden, blocks;
    const float *lengths;
    float damping_squared;
    const float *w_in, *b_in, *w_blocks, *b_blocks, *w_out, *b_out;
    float *scratch, *clean;
} FilmStep;

/* rows first .. first + rows - 1 of the call, through every layer; scratch holds this chunk only */
static void denoise_chunk(const FilmStep *step, int first, int rows, const float *x, const float *target,
                          ptrdiff_t target_stride, const float *film, ptrdiff_t film_stride,
                          ptrdiff_t rows_per_condition) {
    const int links = step->links, hidden = step->hidden, blocks = step->blocks;
    const float *lengths = step->lengths, *w_in = step->w_in, *b_in = step->b_in, *w_blocks = step->w_blocks;
    const float *b_blocks = step->b_blocks, *w_out = step->w_out, *b_out = step->b_out;
    const float damping_squared = step->damping_squared;
    float *scratch = step->scratch;
    const int dim = 2 * links, num_features = dim + 2 + links;
    float *clean = step->clean + (size_t)first * dim;
    x += (size_t)first * dim;
    float *features = scratch;                                  /* (rows, F) */
    float *h = features + (size_t)rows * num_features;          /* (rows, H) */
    float *modulated = h + (size_t)rows * hidden;               /* (rows, H) */
    float *block_output = modulated + (size_t)rows * hidden;    /* (rows, H) */
    float *turn = block_output + (size_t)rows * hidden;         /* (rows, N) */
    float *unit = turn + (size_t)rows * links;                  /* (rows, 2N) */
    const ptrdiff_t scale_offset = (ptrdiff_t)blocks * 2 * hidden;

    const float *row_film[CHUNK]; /* each row's condition: rows_per_condition consecutive rows share one */
    for (int r = 0; r < rows; r++) {
        const size_t condition = (size_t)(first + r) / (size_t)rows_per_condition;
        row_film[r] = film + condition * film_stride;
        row_features(links, x + (size_t)r * dim, target + condition * target_stride, lengths, damping_squared,
                     row_film[r] + scale_offset, unit + (size_t)r * dim, features + (size_t)r * num_features);
    }
    affine(rows, features, num_features, w_in, b_in, hidden, h);
    for (int b = 0; b < blocks; b++) {
        for (int r = 0; r < rows; r++) {
            const float *scale = row_film[r] + (size_t)b * 2 * hidden;
            const float *shift = scale + hidden;
            float *hr = h + (size_t)r * hidden, *mr = modulated + (size_t)r * hidden;
            for (int j = 0; j < hidden; j++) mr[j] = silu(shift[j] + hr[j] * scale[j]);
        }
        affine(rows, modulated, hidden, w_blocks + (size_t)b * hidden * hidden, b_blocks + (size_t)b * hidden,
               hidden, block_output);
        for (size_t i = 0; i < (size_t)rows * hidden; i++) h[i] += block_output[i];
    }
    for (size_t i = 0; i < (size_t)rows * hidden; i++) h[i] = silu(h[i]);
    affine(rows, h, hidden, w_out, b_out, links, turn);
    /* representation.turn: each unit (cos, sin) times e^(i turn) */
    for (int r = 0; r < rows; r++) {
        for (int n = 0; n < links; n++) {
            const float angle = turn[(size_t)r * links + n];
            const float c = cosf(angle), s = sinf(angle);
            const float ux = unit[(size_t)r * dim + 2 * n], uy = unit[(size_t)r * dim + 2 * n + 1];
            clean[(size_t)r * dim + 2 * n] = ux * c - uy * s;
            clean[(size_t)r * dim + 2 * n + 1] = ux * s + uy * c;
        }
    }
}

/* the rows of one chunk: the caller sizes the scratch by it (film_compiled.py asks, never assumes) */
EXPORT int ikdp_film_chunk_rows(void) { return CHUNK; }

EXPORT int ikdp_film_denoise(const FilmStep *step, const float *x, const float *target, ptrdiff_t target_stride,
                             const float *film, ptrdiff_t film_stride, ptrdiff_t rows_per_condition) {
    const int rows = step->rows;
    /* a chunk of rows goes through every layer before the next starts: its activations stay in cache */
    for (int first = 0; first < rows; first += CHUNK) {
        const int count = rows - first < CHUNK ? rows - first : CHUNK;
        denoise_chunk(step, first, count, x, target, target_stride, film, film_stride, rows_per_condition);
    }
    return 0;
}
