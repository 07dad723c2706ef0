/* The onboard endpoint: a native component's C model served over UDP, no Python, no FMI.
 *
 * Built by glider-cosim build-onboard with the component's own C files (its model, its
 * generated variable table, GLIDER_NATIVE_MODEL). It speaks the message format of
 * glider_cosim/realtime/protocol.py, version 1 (little-endian, a 24-byte header then
 * float64 values), and does what the native FMU does for the same calls: start values,
 * the parameters' range checks (the FMU's messages), initialize(), one step per h with
 * the model's own time, and the computed outputs updated before they are read.
 *
 *     PROGRAM [--listen udp://127.0.0.1:9870] [--once]
 */
#include "glider_fp.h"
#include "native_model.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <winsock2.h>
#include <ws2tcpip.h>
typedef int socklen_t;
#else
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>
#endif

#define M GLIDER_NATIVE_MODEL
#define HEADER 24
#define MAX_VALUES 1024
#define MAX_SIZE (HEADER + 8 * MAX_VALUES)

enum { START = 1, READY = 2, INPUTS = 3, OUTPUTS = 4, ERROR_MSG = 5, STOP = 6 };

/* little-endian fields (every target here is little-endian; bytes are assembled anyway) */
static uint32_t get_u32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static void put_u32(unsigned char *p, uint32_t v) {
    p[0] = (unsigned char)v, p[1] = (unsigned char)(v >> 8);
    p[2] = (unsigned char)(v >> 16), p[3] = (unsigned char)(v >> 24);
}
static double get_f64(const unsigned char *p) {
    uint64_t u = (uint64_t)get_u32(p) | (uint64_t)get_u32(p + 4) << 32;
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}
static void put_f64(unsigned char *p, double d) {
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    put_u32(p, (uint32_t)u);
    put_u32(p + 4, (uint32_t)(u >> 32));
}

static size_t header(unsigned char *out, int type, uint32_t seq, double time, uint32_t n) {
    memcpy(out, "GCSM", 4);
    out[4] = 1, out[5] = (unsigned char)type, out[6] = 0, out[7] = 0;
    put_u32(out + 8, seq);
    put_f64(out + 12, time);
    put_u32(out + 20, n);
    return HEADER;
}

static size_t error_reply(unsigned char *out, uint32_t seq, double time, const char *text) {
    size_t n = strlen(text) > 1000 ? 1000 : strlen(text);
    header(out, ERROR_MSG, seq, time, (uint32_t)n);
    memcpy(out + HEADER, text, n);
    return HEADER + n;
}

typedef struct {
    void *data;
    int alive;
    double t0, h, time; /* the start, the step, the model's own time (the FMU's) */
    long j;             /* steps made: the host's time is t0 + j*h, as the master's */
    uint32_t last_seq;  /* of the last INPUTS answered */
    size_t last_len;    /* and its reply, for a repeat */
    unsigned char last[MAX_SIZE];
} Session;

static void *at(Session *s, const NativeVar *v) { return (char *)s->data + v->offset; }
static double number(Session *s, const NativeVar *v) {
    return v->type == 'R' ? *(double *)at(s, v) : (double)*(int *)at(s, v);
}
static void set(Session *s, const NativeVar *v, double value) {
    if (v->type == 'R') *(double *)at(s, v) = value;
    else if (v->type == 'I') *(int *)at(s, v) = (int)value;
    else *(int *)at(s, v) = value != 0.0;
}
static int in_range(const NativeVar *v, double x) {
    if (!isfinite(x)) return 0;
    if (v->low > -HUGE_VAL && (v->low_open ? x <= v->low : x < v->low)) return 0;
    if (v->high < HUGE_VAL && (v->high_open ? x >= v->high : x > v->high)) return 0;
    return 1;
}

/* START: start values, the parameters, their checks, initialize(); 0 or a message */
static int start(Session *s, const unsigned char *body, uint32_t n, double t0, char *msg,
                 size_t size) {
    size_t i;
    char text[64];
    if (n < 1 || n % 2 != 1 || !(get_f64(body) > 0.0))
        return snprintf(msg, size, "malformed: START needs [h, vr, value, ...] with h > 0"), 1;
    memset(s->data, 0, M.data_size);
    for (i = 0; i < M.nvars; ++i) set(s, &M.vars[i], M.vars[i].start);
    s->h = get_f64(body), s->t0 = s->time = t0, s->j = 0, s->last_seq = 0, s->last_len = 0;
    for (i = 1; i < n; i += 2) {
        double vr = get_f64(body + 8 * i), value = get_f64(body + 8 * (i + 1));
        if (!(vr >= 0 && vr < (double)M.nvars) || M.vars[(size_t)vr].causality == NV_OUTPUT)
            return snprintf(msg, size, "START sets value reference %.0f: no parameter", vr), 1;
        set(s, &M.vars[(size_t)vr], value);
    }
    for (i = 0; i < M.nvars; ++i) {
        const NativeVar *v = &M.vars[i];
        if (!v->has_range || v->causality == NV_OUTPUT || in_range(v, number(s, v))) continue;
        if (v->type == 'R') py_float_repr(number(s, v), text, sizeof text);
        else snprintf(text, sizeof text, "%d", (int)number(s, v));
        return snprintf(msg, size, "%s = %s is invalid: expected %s", v->name, text,
                        v->expected), 1;
    }
    if (M.initialize(s->data, msg, size) != NATIVE_OK) return 1;
    s->alive = 1;
    return 0;
}

/* INPUTS: step to the request's time, set the inputs, the outputs (reply length) */
static size_t inputs(Session *s, uint32_t seq, double time, const unsigned char *body,
                     uint32_t n, unsigned char *out) {
    char msg[1024] = "", warning[1024] = "";
    size_t i, k = 0, nin = 0;
    if (s->last_len && seq == s->last_seq) {
        memcpy(out, s->last, s->last_len);
        return s->last_len;
    }
    if ((s->last_len && seq < s->last_seq) || time < s->t0 + s->j * s->h - s->h / 2) return 0;
    for (i = 0; i < M.nvars; ++i) nin += M.vars[i].causality == NV_INPUT;
    if (n != nin) return error_reply(out, seq, time, "refused: INPUTS of the wrong size");
    while (s->t0 + s->j * s->h < time - s->h / 2) {
        double t = s->t0 + s->j * s->h;
        int r = M.step(s->data, t, s->time, s->h, msg, sizeof msg, warning, sizeof warning);
        if (r != NATIVE_OK) return s->alive = 0, error_reply(out, seq, time, msg);
        s->time = t + s->h;
        s->j += 1;
    }
    for (i = 0; i < M.nvars; ++i)
        if (M.vars[i].causality == NV_INPUT) set(s, &M.vars[i], get_f64(body + 8 * k++));
    if (M.update) M.update(s->data, s->time, 1);
    k = 0;
    for (i = 0; i < M.nvars; ++i)
        if (M.vars[i].causality == NV_OUTPUT) put_f64(out + HEADER + 8 * k++, number(s, &M.vars[i]));
    header(out, OUTPUTS, seq, time, (uint32_t)k);
    s->last_seq = seq;
    s->last_len = HEADER + 8 * k;
    memcpy(s->last, out, s->last_len);
    return s->last_len;
}

int main(int argc, char **argv) {
    const char *listen = "udp://127.0.0.1:9870";
    char host[64];
    int port, once = 0, i, fd;
    struct sockaddr_in addr, peer, from;
    socklen_t len = sizeof addr;
    static unsigned char in[MAX_SIZE + 1], out[MAX_SIZE];
    Session s;
    for (i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--listen") && i + 1 < argc) listen = argv[++i];
        else if (!strcmp(argv[i], "--once")) once = 1;
        else return fprintf(stderr, "usage: %s [--listen udp://HOST:PORT] [--once]\n", argv[0]), 2;
    }
    if (sscanf(listen, "udp://%63[0-9.]:%d", host, &port) != 2 || port < 0 || port > 65535)
        return fprintf(stderr, "--listen %s is invalid: expected udp://IPV4:PORT\n", listen), 2;
#ifdef _WIN32
    {
        WSADATA w;
        if (WSAStartup(MAKEWORD(2, 2), &w)) return fprintf(stderr, "no sockets\n"), 1;
    }
#endif
    memset(&addr, 0, sizeof addr);
    addr.sin_family = AF_INET;
    addr.sin_port = htons((unsigned short)port);
    if (inet_pton(AF_INET, host, &addr.sin_addr) != 1)
        return fprintf(stderr, "--listen %s: %s is not an IPv4 address\n", listen, host), 2;
    fd = (int)socket(AF_INET, SOCK_DGRAM, 0);
    if (fd < 0 || bind(fd, (struct sockaddr *)&addr, sizeof addr) != 0)
        return fprintf(stderr, "--listen %s: cannot bind\n", listen), 1;
    getsockname(fd, (struct sockaddr *)&addr, &len);
    printf("serving %s on udp://%s:%d\n", M.identifier, host, ntohs(addr.sin_port));
    fflush(stdout);
    memset(&s, 0, sizeof s);
    memset(&peer, 0, sizeof peer);
    if (!(s.data = malloc(M.data_size))) return fprintf(stderr, "out of memory\n"), 1;
    for (;;) {
        socklen_t flen = sizeof from;
        int got = (int)recvfrom(fd, (char *)in, sizeof in, 0, (struct sockaddr *)&from, &flen);
        size_t reply = 0;
        uint32_t seq, n;
        double time;
        int same;
        if (got < HEADER || got > MAX_SIZE || memcmp(in, "GCSM", 4) || in[4] != 1) continue;
        seq = get_u32(in + 8), time = get_f64(in + 12), n = get_u32(in + 20);
        if (n > MAX_VALUES || (size_t)got != HEADER + 8 * (size_t)n) continue;
        same = s.alive && from.sin_addr.s_addr == peer.sin_addr.s_addr &&
               from.sin_port == peer.sin_port;
        if (in[5] == START) {
            char msg[1024] = "";
            peer = from;
            s.alive = 0;
            if (start(&s, in + HEADER, n, time, msg, sizeof msg)) {
                char text[1100];
                snprintf(text, sizeof text, "refused: %s", msg);
                reply = error_reply(out, seq, time, text);
            } else {
                reply = header(out, READY, seq, time, 0);
            }
        } else if (in[5] == INPUTS && same) {
            reply = inputs(&s, seq, time, in + HEADER, n, out);
        } else if (in[5] == STOP && same) {
            s.alive = 0;
            if (once) break;
        }
        if (reply)
            sendto(fd, (const char *)out, (int)reply, 0, (struct sockaddr *)&from, sizeof from);
    }
    free(s.data);
#ifdef _WIN32
    closesocket(fd);
    WSACleanup();
#else
    close(fd);
#endif
    return 0;
}
