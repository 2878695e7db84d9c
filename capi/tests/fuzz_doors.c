/*
 * A fuzzer of the C interface's doors (issue 39), run by capi/tests/c_fuzz.rs: hostile
 * scenario JSON, edges and options into agglo_coupling_new; cell inputs drawn from
 * extreme values into agglo_cell_advance and agglo_cells_advance (batches with
 * repeated and foreign states); mutated state bytes into agglo_state_from_bytes; and
 * unknown names and lengths into agglo_output_get. Every call must return a status in
 * the enum with a message, never abort, and keep its contract (a failed call writes no
 * handle; a batch writes every status; changed state bytes are refused).
 *
 *   usage: fuzz_doors SCENARIO.json SEED SECONDS
 * Deterministic for a seed; stops drawing new cases after SECONDS (the time bound) and
 * prints the cases run. Exits 0 when every contract held, 1 with the first breach.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "agglo.h"

#define CLASSES 3

static uint64_t rng_state;

/* splitmix64: a fixed stream per seed. */
static uint64_t next_u64(void) {
  uint64_t z = (rng_state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

static size_t below(size_t n) { return n ? (size_t)(next_u64() % n) : 0; }

static int breaches = 0;

static void breach(const char *what, int status) {
  if (breaches++ == 0)
    printf("BREACH: %s (status %d): %s\n", what, status, agglo_last_error());
}

/* A status from the enum with a message when it is not OK. */
static int checked(AggloStatus status, const char *what) {
  if ((int)status < AGGLO_STATUS_OK || (int)status > AGGLO_STATUS_INTERNAL)
    breach(what, (int)status);
  else if (status == AGGLO_STATUS_INTERNAL)
    breach(what, (int)status); /* a caught panic is a bug, not an answer */
  else if (status != AGGLO_STATUS_OK && strlen(agglo_last_error()) == 0)
    breach(what, (int)status);
  return (int)status;
}

/* Values a hostile caller passes: signs, zeros, subnormals, huge, non-finite. */
static double extreme(void) {
  static const double values[] = {0.0,     -0.0,    -1.0,     1.0,    5e-324, 1e-320,
                                  1e-300,  1e-30,   1e-6,     300.0,  1e5,    1.0001e5,
                                  1e154,   1e200,   1e300,    -1e300, 0.5,    2.0};
  size_t n = sizeof values / sizeof values[0];
  switch (below(4)) {
    case 0: return NAN;
    case 1: return below(2) ? INFINITY : -INFINITY;
    default: return values[below(n)];
  }
}

/* A value near `good` most of the time, an extreme one sometimes: most cases then
   pass the early checks and reach the later ones. */
static double near(double good) { return below(10) ? good : extreme(); }

static char *read_file(const char *path, size_t *len) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *text = malloc((size_t)size + 1);
  *len = fread(text, 1, (size_t)size, f);
  text[*len] = 0;
  fclose(f);
  return text;
}

/* The scenario text damaged one way: cut, a byte changed, a number replaced. */
static char *mutated(const char *seed, size_t len) {
  static const char *numbers[] = {"1e308", "-1", "0", "NaN", "1e-320", "4294967296",
                                  "18446744073709551616", "\"x\"", "null", "[]", "{}"};
  char *text = malloc(len + 64);
  memcpy(text, seed, len + 1);
  switch (below(3)) {
    case 0: text[below(len)] = 0; break;
    case 1: text[below(len)] = (char)(1 + below(255)); break;
    default: {
      /* Replace the digits of a number with another value. */
      size_t at = below(len);
      while (at < len && !(text[at] >= '0' && text[at] <= '9')) at++;
      if (at >= len) break;
      size_t end = at;
      while (end < len && strchr("0123456789.e-+", text[end])) end++;
      const char *with = numbers[below(sizeof numbers / sizeof numbers[0])];
      char *out = malloc(len + 64);
      memcpy(out, text, at);
      strcpy(out + at, with);
      strcat(out, text + end);
      free(text);
      text = out;
    }
  }
  return text;
}

typedef struct {
  double n[CLASSES], m[CLASSES], v[3 * CLASSES], theta[CLASSES], tg[CLASSES];
  double aniso[3 * CLASSES];
  AggloCellInput in;
} Cell;

/* A cell whose every field is drawn near a good value. */
static void draw_cell(Cell *c, const double *edges, double n0) {
  for (int k = 0; k < CLASSES; k++) {
    c->n[k] = near(k == 0 ? n0 : 0.1 * n0);
    c->m[k] = near(edges[k] * (k == 0 ? 2.0 : 1.5));
    for (int x = 0; x < 3; x++) c->v[3 * k + x] = near(0.0);
    c->theta[k] = near(300.0);
    c->tg[k] = near(1.0);
    for (int x = 0; x < 3; x++) c->aniso[3 * k + x] = near(1.0);
  }
  c->in.number_density = c->n;
  c->in.mass = c->m;
  c->in.velocity = c->v;
  c->in.temperature = c->theta;
  c->in.granular_temperature = c->tg;
  /* NULL (isotropic) half the time, else weights drawn near 1. */
  c->in.granular_anisotropy = below(2) ? NULL : c->aniso;
  for (int x = 0; x < 3; x++) c->in.gas.velocity[x] = near(0.0);
  c->in.gas.temperature = near(300.0);
  c->in.gas.drag = below(4) ? AGGLO_DRAG_NONE : (uint32_t)below(6);
  c->in.gas.drag_a = near(1e-3);
  c->in.gas.drag_b = near(400.0);
  c->in.dt = near(1e-5);
}

static double seconds_since(clock_t start) {
  return (double)(clock() - start) / CLOCKS_PER_SEC;
}

int main(int argc, char **argv) {
  if (argc != 4) {
    fprintf(stderr, "usage: %s SCENARIO.json SEED SECONDS\n", argv[0]);
    return 2;
  }
  rng_state = strtoull(argv[2], NULL, 10);
  double budget = atof(argv[3]);
  size_t len = 0;
  char *scenario = read_file(argv[1], &len);
  if (!scenario) {
    fprintf(stderr, "cannot read %s\n", argv[1]);
    return 2;
  }
  double b0, m0;
  if (agglo_scenario_primary(scenario, &b0, &m0) != AGGLO_STATUS_OK) {
    fprintf(stderr, "the seed scenario: %s\n", agglo_last_error());
    return 2;
  }
  /* Classes of 1, 2–3 and 4+ primaries; monomers at volume fraction 0.02. */
  const double edges[CLASSES + 1] = {0.5 * m0, 1.5 * m0, 3.5 * m0, 1e9 * m0};
  const double n0 = 0.02 / (4.0 / 3.0 * 3.14159265358979 * b0 * b0 * b0);
  AggloCouplingOptions small = agglo_coupling_options_default();
  small.bodies = 24;
  small.replicas = 2;
  AggloCoupling *open = NULL, *closed = NULL;
  if (agglo_coupling_new(scenario, edges, CLASSES + 1, &small, &open) != AGGLO_STATUS_OK)
    return fprintf(stderr, "coupling: %s\n", agglo_last_error()), 2;
  small.keep_bodies = 1;
  small.persist = 0; /* a closed cell: its kept bodies, not adjusted to the input */
  if (agglo_coupling_new(scenario, edges, CLASSES + 1, &small, &closed) != AGGLO_STATUS_OK)
    return fprintf(stderr, "coupling: %s\n", agglo_last_error()), 2;

  /* A kept state to damage: one good step of a closed cell. */
  Cell good;
  draw_cell(&good, edges, n0); /* the pointers; every value is then set good */
  for (int k = 0; k < CLASSES; k++) {
    good.n[k] = k == 0 ? n0 : 0.0;
    good.m[k] = edges[k] * (k == 0 ? 2.0 : 1.5);
    good.v[3 * k] = good.v[3 * k + 1] = good.v[3 * k + 2] = 0.0;
    good.theta[k] = 300.0;
    good.tg[k] = 1.0;
  }
  good.in.granular_anisotropy = NULL;
  good.in.gas.velocity[0] = good.in.gas.velocity[1] = good.in.gas.velocity[2] = 0.0;
  good.in.gas.temperature = 300.0;
  good.in.gas.drag = AGGLO_DRAG_NONE;
  good.in.dt = 1e-5;
  AggloCellState *kept = NULL;
  AggloOutput *out = NULL;
  if (agglo_cell_advance(closed, 1, 0, &good.in, &kept, &out) != AGGLO_STATUS_OK)
    return fprintf(stderr, "good cell: %s\n", agglo_last_error()), 2;
  size_t n_bytes = 0;
  agglo_state_to_bytes(kept, NULL, 0, &n_bytes);
  uint8_t *bytes = malloc(n_bytes);
  agglo_state_to_bytes(kept, bytes, n_bytes, &n_bytes);

  clock_t start = clock();
  long cases[5] = {0, 0, 0, 0, 0}, accepted[5] = {0, 0, 0, 0, 0};
  while (seconds_since(start) < budget && breaches == 0) {
    switch (below(5)) {
      case 0: { /* scenario, edges and options */
        char *text = mutated(scenario, len);
        double e[6];
        size_t ne = below(6);
        for (size_t i = 0; i < ne; i++) e[i] = below(3) ? edges[i % (CLASSES + 1)] : extreme();
        AggloCouplingOptions o = agglo_coupling_options_default();
        o.bodies = below(2) ? 24 : (uint32_t)next_u64();
        o.replicas = below(2) ? 2 : (uint32_t)next_u64();
        o.target_se = near(0.05);
        o.min_bodies = (uint32_t)below(200);
        o.max_bodies = below(2) ? 1000 : (uint32_t)next_u64();
        o.keep_bodies = below(2);
        o.persist = below(2);
        AggloCoupling *c = NULL;
        int s = checked(agglo_coupling_new(text, ne ? e : edges, ne ? ne : CLASSES + 1,
                                           below(4) ? &o : NULL, &c),
                        "agglo_coupling_new");
        if ((s == AGGLO_STATUS_OK) != (c != NULL)) breach("coupling handle and status", s);
        accepted[0] += s == AGGLO_STATUS_OK;
        agglo_coupling_free(c);
        free(text);
        cases[0]++;
        break;
      }
      case 1: { /* one cell */
        Cell cell;
        draw_cell(&cell, edges, n0);
        AggloCellState *state = NULL;
        AggloOutput *o = NULL;
        int s = checked(agglo_cell_advance(below(2) ? open : closed, next_u64(), below(3),
                                           &cell.in, &state, &o),
                        "agglo_cell_advance");
        if ((s == AGGLO_STATUS_OK) != (o != NULL && state != NULL))
          breach("cell handles and status", s);
        if (s == AGGLO_STATUS_OK) {
          double mean[CLASSES];
          checked(agglo_output_get(o, "number_rate", mean, NULL, CLASSES), "output");
        }
        accepted[1] += s == AGGLO_STATUS_OK;
        agglo_output_free(o);
        agglo_state_free(state);
        cases[1]++;
        break;
      }
      case 2: { /* a batch: drawn cells, the kept state repeated or foreign */
        enum { MAX_BATCH = 4 };
        Cell cells[MAX_BATCH];
        uint64_t ids[MAX_BATCH];
        AggloCellInput inputs[MAX_BATCH];
        AggloCellState *states[MAX_BATCH];
        AggloOutput *outs[MAX_BATCH];
        AggloStatus statuses[MAX_BATCH];
        size_t n = 1 + below(MAX_BATCH);
        AggloCellState *copy = NULL;
        agglo_state_from_bytes(bytes, n_bytes, &copy);
        for (size_t i = 0; i < n; i++) {
          draw_cell(&cells[i], edges, n0);
          inputs[i] = below(2) ? cells[i].in : good.in;
          ids[i] = below(2) ? 1 : 2 + i;
          states[i] = below(3) ? NULL : copy;
          outs[i] = (AggloOutput *)0;
          statuses[i] = (AggloStatus)99;
        }
        int given = 0;
        for (size_t i = 0; i < n; i++) given |= states[i] == copy;
        int s = checked(agglo_cells_advance(closed, 1, n, ids, inputs, states, outs, statuses,
                                            below(3)),
                        "agglo_cells_advance");
        int any_failed = 0;
        for (size_t i = 0; i < n; i++) {
          if ((int)statuses[i] == 99) breach("a batch status left unwritten", s);
          checked(statuses[i], "a batch entry");
          if ((statuses[i] == AGGLO_STATUS_OK) != (outs[i] != NULL))
            breach("a batch output and its status", (int)statuses[i]);
          any_failed |= statuses[i] != AGGLO_STATUS_OK;
        }
        if (any_failed != (s != AGGLO_STATUS_OK)) breach("the batch status", s);
        /* Free each distinct state once: an entry that advanced replaced (and freed)
           the copy it was given; a refused one still holds it. */
        for (size_t i = 0; i < n; i++) {
          agglo_output_free(outs[i]);
          int seen = 0;
          for (size_t j = 0; j < i; j++) seen |= states[j] == states[i];
          if (!seen) agglo_state_free(states[i]);
        }
        if (!given) agglo_state_free(copy);
        accepted[2] += s == AGGLO_STATUS_OK;
        cases[2]++;
        break;
      }
      case 3: { /* state bytes: flips, cuts, extensions */
        size_t n = n_bytes + (below(4) == 0 ? below(16) : 0);
        uint8_t *b = malloc(n + 1);
        memcpy(b, bytes, n_bytes < n ? n_bytes : n);
        for (size_t i = n_bytes; i < n; i++) b[i] = (uint8_t)next_u64();
        size_t flips = below(4);
        for (size_t i = 0; i < flips; i++) b[below(n_bytes)] ^= (uint8_t)(1u << below(8));
        size_t use = below(4) == 0 ? below(n + 1) : n;
        int same = use == n_bytes && memcmp(b, bytes, n_bytes) == 0;
        AggloCellState *st = NULL;
        int s = checked(agglo_state_from_bytes(b, use, &st), "agglo_state_from_bytes");
        if (same != (s == AGGLO_STATUS_OK)) breach("changed bytes accepted, or the state refused", s);
        if ((s == AGGLO_STATUS_OK) != (st != NULL)) breach("state handle and status", s);
        accepted[3] += s == AGGLO_STATUS_OK;
        agglo_state_free(st);
        free(b);
        cases[3]++;
        break;
      }
      default: { /* output names and lengths */
        static const char *names[] = {"number_rate", "velocity", "bodies", "", "number_rate ",
                                      "NUMBER_RATE", "kernel_bonds", "\xff\xfe"};
        const char *name = names[below(sizeof names / sizeof names[0])];
        size_t want = below(3 * CLASSES + 2);
        double mean[3 * CLASSES + 2], se[3 * CLASSES + 2];
        size_t have = 0;
        int known = agglo_output_len(out, name, &have) == AGGLO_STATUS_OK;
        int s = checked(agglo_output_get(out, name, mean, below(2) ? se : NULL, want),
                        "agglo_output_get");
        if ((s == AGGLO_STATUS_OK) != (known && want == have))
          breach("an output length or name", s);
        accepted[4] += s == AGGLO_STATUS_OK;
        cases[4]++;
      }
    }
  }
  printf("cases (accepted): coupling %ld (%ld), cell %ld (%ld), batch %ld (%ld), "
         "state bytes %ld (%ld), output %ld (%ld) in %.1f s\n",
         cases[0], accepted[0], cases[1], accepted[1], cases[2], accepted[2], cases[3],
         accepted[3], cases[4], accepted[4], seconds_since(start));
  agglo_output_free(out);
  agglo_state_free(kept);
  agglo_coupling_free(open);
  agglo_coupling_free(closed);
  free(bytes);
  free(scenario);
  return breaches ? 1 : 0;
}
