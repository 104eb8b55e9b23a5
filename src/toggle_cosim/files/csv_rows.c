/* Trace rows as CSV text: each double as printf("%.17g") writes it, ',' between values, '\n'
   after each row (the bytes np.savetxt(fmt="%.17g", delimiter=",") writes). Built and cached on
   the user's machine by toggle_cosim.files.csv_rows.

   glibc's printf gives the exact binary value rounded to 17 significant digits (to nearest, ties
   to even), through arbitrary-precision arithmetic: about 0.4 us a value. Here the 17 digits are
   computed with 128-bit integers for the values a trace holds: v = m 2^e (m < 2^53) has the digits
   N = round(v 10^k), k = 16 - X, X = floor(log10 |v|) after rounding; for 0 <= k <= 27
   (1e-11 <= |v| < 1e17), v 10^k = m 5^k 2^(e+k) with m 5^k < 2^53 2^63, so N and its rounding
   are exact. Zero is "0" or "-0"; every other value (tiny, huge, inf, subnormal) goes to snprintf, as does every
   value where the compiler has no 128-bit integer. NaN is written "nan" whatever its sign. */

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

static int slow(double v, char *out) { return snprintf(out, 32, "%.17g", v); }

#ifdef __SIZEOF_INT128__
typedef unsigned __int128 u128;

static const uint64_t P17 = 100000000000000000ULL, P16 = 10000000000000000ULL;

static uint64_t FIVE[28];
static double TEN[61];
__attribute__((constructor)) static void tables(void) {
    FIVE[0] = 1;
    for (int i = 1; i < 28; i++) FIVE[i] = FIVE[i - 1] * 5;
    for (int i = 0; i < 61; i++) TEN[i] = pow(10.0, i - 30);
}

/* 17 digits of |v| (N in [1e16, 1e17)) and the exponent X; 0 if the fast route cannot say. */
static int digits17(double a, uint64_t *digits, int *exponent) {
    int E;
    double f = frexp(a, &E);                 /* a = f 2^E, f in [0.5, 1) */
    if (E < -1021) return 0;                 /* subnormal or near: snprintf */
    uint64_t m = (uint64_t)ldexp(f, 53);     /* exact: f has 53 significant bits */
    int e = E - 53;
    int X = ((E - 1) * 78913) >> 18;          /* floor(log10 2^(E-1)) for the E here */
    if (X + 1 >= -30 && X + 1 <= 30 && a >= TEN[X + 1 + 30]) X++;
    for (int attempt = 0; attempt < 3; attempt++) {
        int k = 16 - X;
        if (k < 0 || k > 27) return 0;
        u128 p = (u128)m * FIVE[k];
        int t = e + k;
        u128 q, r = 0, half = 0;
        int s = 0;
        if (t >= 0) {
            if (t > 63 || (p >> (127 - t)) != 0) return 0;
            q = p << t;
        } else {
            s = -t;
            if (s >= 127) return 0;
            q = p >> s;
            r = p & (((u128)1 << s) - 1);
            half = (u128)1 << (s - 1);
        }
        if (q >= (u128)P17) { X++; continue; }
        if (q < (u128)P16) { X--; continue; }
        uint64_t n = (uint64_t)q;
        if (s > 0 && (r > half || (r == half && (n & 1)))) n++;
        if (n == P17) { n = P16; X++; }
        *digits = n;
        *exponent = X;
        return 1;
    }
    return 0;
}

#else
static int digits17(double a, uint64_t *digits, int *exponent) { (void)a; (void)digits; (void)exponent; return 0; }
#endif

static int format17(double v, char *out) {
    if (isnan(v)) { memcpy(out, "nan", 3); return 3; }
    if (v == 0.0) {
        if (signbit(v)) { memcpy(out, "-0", 2); return 2; }
        out[0] = '0';
        return 1;
    }
    if (isinf(v)) return slow(v, out);
    uint64_t n;
    int X;
    double a = fabs(v);
    if (!digits17(a, &n, &X)) return slow(v, out);
    char d[17];
    uint32_t hi = (uint32_t)(n / 100000000ULL), lo = (uint32_t)(n % 100000000ULL);
    for (int i = 16; i >= 9; i--) { d[i] = (char)('0' + lo % 10); lo /= 10; }
    for (int i = 8; i >= 0; i--) { d[i] = (char)('0' + hi % 10); hi /= 10; }
    int last = 16;                           /* %g drops trailing zeros */
    while (last > 0 && d[last] == '0') last--;
    char *o = out;
    if (v < 0) *o++ = '-';
    if (X >= -4 && X < 17) {
        if (X >= 0) {
            memcpy(o, d, (size_t)X + 1); o += X + 1;
            if (last > X) { *o++ = '.'; memcpy(o, d + X + 1, (size_t)(last - X)); o += last - X; }
        } else {
            *o++ = '0'; *o++ = '.';
            for (int i = 0; i < -X - 1; i++) *o++ = '0';
            memcpy(o, d, (size_t)last + 1); o += last + 1;
        }
    } else {
        *o++ = d[0];
        if (last > 0) { *o++ = '.'; memcpy(o, d + 1, (size_t)last); o += last; }
        *o++ = 'e';
        int x = X;
        if (x < 0) { *o++ = '-'; x = -x; } else *o++ = '+';
        if (x >= 100) { *o++ = (char)('0' + x / 100); x %= 100; }
        *o++ = (char)('0' + x / 10); *o++ = (char)('0' + x % 10);
    }
    return (int)(o - out);
}

/* n x m doubles (row-major); the number of bytes written, or -1 if `capacity` is too small. */
long format_rows(const double *data, long n, long m, char *out, long capacity) {
    long used = 0;
    for (long i = 0; i < n; i++) {
        for (long j = 0; j < m; j++) {
            if (capacity - used < 32) return -1;
            used += format17(data[i * m + j], out + used);
            out[used++] = (j + 1 < m) ? ',' : '\n';
        }
    }
    return used;
}
