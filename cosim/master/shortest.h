/* Python's repr() of a double, fast (shortest.c). */
#ifndef GLIDER_SHORTEST_H
#define GLIDER_SHORTEST_H

/* Longest text glider_repr writes: "-1.2345678901234567e-308" */
#define GLIDER_REPR_MAX 24
/* Bytes glider_repr may overwrite at out (past the text: scratch, for fixed-size copies) */
#define GLIDER_REPR_ROOM 40

/* Writes repr(v) at out (room for GLIDER_REPR_ROOM bytes, no terminating NUL); returns
 * the text's length. */
int glider_repr(double v, char *out);

#endif
