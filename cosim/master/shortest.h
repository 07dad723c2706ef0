/* Python's repr() of a double, fast (shortest.c). */
#ifndef GLIDER_SHORTEST_H
#define GLIDER_SHORTEST_H

/* Longest text glider_repr writes: "-1.2345678901234567e-308" */
#define GLIDER_REPR_MAX 24

/* Writes repr(v) at out (at least GLIDER_REPR_MAX bytes, no terminating NUL); returns
 * its length. */
int glider_repr(double v, char *out);

#endif
