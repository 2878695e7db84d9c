/*
 * A flow solver's view of agglo: eight cells of sticky grains, three macro steps, each
 * step's cells advanced as one batch on two threads; then the same cell alone (the same
 * bytes), a state kept as bytes and made again, and a bad input refused by name.
 *
 * Build (from the repository root, after `cargo build -p agglo-capi`):
 *   cc -std=c99 -Wall -Wextra -Icapi/include capi/examples/advance_cells.c \
 *      -Ltarget/debug -lagglo_c -Wl,-rpath,$PWD/target/debug -lm -o advance_cells
 *   ./advance_cells scenarios/ballistic_aggregation.json
 * Exits 0 when every check holds, 1 otherwise (capi/tests/c_program.rs runs it).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "agglo.h"

#define CELLS 8
#define CLASSES 5
#define STEPS 3

static const double PI = 3.14159265358979323846;

/* Stop with the library's message when a call fails. */
static void check(AggloStatus status, const char *what) {
  if (status != AGGLO_STATUS_OK) {
    fprintf(stderr, "%s failed (status %d): %s\n", what, (int)status, agglo_last_error());
    exit(1);
  }
}

/* The cell's macro state: monomers at volume fraction phi, at rest on average. */
typedef struct {
  double n[CLASSES], m[CLASSES], v[3 * CLASSES], theta[CLASSES], tg[CLASSES];
} Cell;

static void monomers(Cell *c, double phi, double b0, double m0) {
  const double per_class[CLASSES] = {1, 2, 3, 5, 9}; /* primaries per body */
  for (int k = 0; k < CLASSES; k++) {
    c->n[k] = k == 0 ? phi / (4.0 / 3.0 * PI * b0 * b0 * b0) : 0.0;
    c->m[k] = per_class[k] * m0;
    c->v[3 * k] = c->v[3 * k + 1] = c->v[3 * k + 2] = 0.0;
    c->theta[k] = 300.0;
    c->tg[k] = 1.0; /* granular temperature [m^2/s^2] */
  }
}

static AggloCellInput input_of(const Cell *c, double dt) {
  AggloCellInput in;
  in.number_density = c->n;
  in.mass = c->m;
  in.velocity = c->v;
  in.temperature = c->theta;
  in.granular_temperature = c->tg;
  in.granular_anisotropy = NULL; /* isotropic */
  in.gas.velocity[0] = in.gas.velocity[1] = in.gas.velocity[2] = 0.0;
  in.gas.temperature = 300.0;
  in.gas.drag = AGGLO_DRAG_NONE;
  in.gas.drag_a = in.gas.drag_b = 0.0;
  in.dt = dt;
  return in;
}

int main(int argc, char **argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: %s SCENARIO.json\n", argv[0]);
    return 2;
  }
  printf("agglo %s\n", agglo_version());
  AggloCouplingOptions options = agglo_coupling_options_default();
  options.bodies = 300;
  options.replicas = 2;

  /* Classes by primaries: 1, 2, 3-4, 5-8, 9 and up: edges in units of the primary
     grain's mass m0, read from the scenario. */
  double unit_edges[CLASSES + 1] = {0.5, 1.5, 2.5, 4.5, 8.5, 1e9};
  double b0, m0;
  check(agglo_scenario_primary_load(argv[1], &b0, &m0), "primary");
  double edges[CLASSES + 1];
  for (int k = 0; k <= CLASSES; k++) edges[k] = unit_edges[k] * m0;
  AggloCoupling *coupling = NULL;
  check(agglo_coupling_load(argv[1], edges, CLASSES + 1, &options, &coupling), "coupling");
  if (agglo_coupling_classes(coupling) != CLASSES) return 1;

  Cell cells[CELLS];
  uint64_t ids[CELLS];
  AggloCellInput inputs[CELLS];
  AggloCellState *states[CELLS] = {0};
  AggloOutput *outs[CELLS] = {0};
  AggloStatus statuses[CELLS];
  const double dt = 2e-4;
  for (int i = 0; i < CELLS; i++) {
    ids[i] = 100 + (uint64_t)i;
    monomers(&cells[i], 0.02 + 0.005 * i, b0, m0);
    inputs[i] = input_of(&cells[i], dt);
  }
  int failures = 0;
  for (uint64_t step = 0; step < STEPS; step++) {
    check(agglo_cells_advance(coupling, step, CELLS, ids, inputs, states, outs, statuses, 2),
          "cells");
    for (int i = 0; i < CELLS; i++) {
      double rate[CLASSES], rate_se[CLASSES], mass_rate[CLASSES];
      check(agglo_output_get(outs[i], "number_rate", rate, rate_se, CLASSES), "number_rate");
      check(agglo_output_get(outs[i], "mass_rate", mass_rate, NULL, CLASSES), "mass_rate");
      /* Grains merge: monomers are lost, and no mass is made or lost overall. */
      double total = 0, scale = fabs(mass_rate[0]);
      for (int k = 0; k < CLASSES; k++) total += mass_rate[k];
      if (!(rate[0] < 0) || fabs(total) > 1e-12 * scale) {
        fprintf(stderr, "cell %d step %d: dn0/dt %g, mass rates sum to %g of %g\n", i,
                (int)step, rate[0], total, scale);
        failures++;
      }
      if (i == 0 || i == CELLS - 1)
        printf("step %d cell %llu: dn0/dt = %.4e +- %.2e, dn1/dt = %.4e 1/(m^3 s)\n",
               (int)step, (unsigned long long)ids[i], rate[0], rate_se[0], rate[1]);
      /* The next step starts from the cell's new class densities (a flow solver would
         transport them first). */
      double density[CLASSES];
      check(agglo_output_get(outs[i], "number_density", density, NULL, CLASSES), "density");
      for (int k = 0; k < CLASSES; k++) cells[i].n[k] = density[k];
      if (step + 1 < STEPS) agglo_output_free(outs[i]);
    }
  }

  /* Cell 3's last step alone: the same figures as in the batch, bit for bit. */
  {
    Cell again;
    monomers(&again, 0.02 + 0.005 * 3, b0, m0);
    AggloCellState *state = NULL;
    AggloOutput *alone = NULL;
    for (uint64_t step = 0; step < STEPS; step++) {
      AggloCellInput in = input_of(&again, dt);
      if (alone) agglo_output_free(alone);
      alone = NULL;
      check(agglo_cell_advance(coupling, ids[3], step, &in, &state, &alone), "cell");
      check(agglo_output_get(alone, "number_density", again.n, NULL, CLASSES), "density");
    }
    size_t len = 0;
    check(agglo_output_len(alone, "velocity", &len), "len");
    double *a = malloc(len * sizeof *a), *b = malloc(len * sizeof *b);
    check(agglo_output_get(alone, "velocity", a, NULL, len), "velocity");
    check(agglo_output_get(outs[3], "velocity", b, NULL, len), "velocity");
    if (len != 3 * CLASSES || memcmp(a, b, len * sizeof *a) != 0) {
      fprintf(stderr, "cell %llu alone differs from its batch entry\n",
              (unsigned long long)ids[3]);
      failures++;
    } else {
      printf("cell %llu alone: the same bytes as in the batch\n", (unsigned long long)ids[3]);
    }
    free(a);
    free(b);

    /* get_state / set_state: the bytes make the same state again. */
    size_t n_bytes = 0;
    check(agglo_state_to_bytes(state, NULL, 0, &n_bytes), "state size");
    unsigned char *bytes = malloc(n_bytes);
    check(agglo_state_to_bytes(state, bytes, n_bytes, &n_bytes), "state bytes");
    AggloCellState *copy = NULL;
    check(agglo_state_from_bytes(bytes, n_bytes, &copy), "state from bytes");
    size_t n_again = 0;
    check(agglo_state_to_bytes(copy, NULL, 0, &n_again), "state size");
    if (n_again != n_bytes) failures++;
    printf("state: %zu bytes, made again\n", n_bytes);
    /* Damaged bytes are refused and leave `copy` as it was: one flipped bit (the bytes
       end in a CRC-32), then the bytes cut short. */
    AggloCellState *kept = copy;
    bytes[n_bytes / 2] ^= 0x01;
    if (agglo_state_from_bytes(bytes, n_bytes, &copy) != AGGLO_STATUS_STATE) failures++;
    bytes[n_bytes / 2] ^= 0x01;
    if (agglo_state_from_bytes(bytes, n_bytes / 2, &copy) != AGGLO_STATUS_STATE) failures++;
    if (copy != kept) failures++;
    printf("damaged state: refused: %s\n", agglo_last_error());
    free(bytes);
    agglo_state_free(copy);
    agglo_state_free(state);
    agglo_output_free(alone);
  }

  /* Bad input: a negative density is refused, naming the cell and the field. */
  {
    Cell bad;
    monomers(&bad, 0.02, b0, m0);
    bad.n[2] = -1.0;
    AggloCellInput in = input_of(&bad, dt);
    AggloCellState *state = NULL;
    AggloOutput *out = NULL;
    AggloStatus status = agglo_cell_advance(coupling, 7, 0, &in, &state, &out);
    printf("bad input: status %d: %s\n", (int)status, agglo_last_error());
    if (status != AGGLO_STATUS_INPUT || out != NULL ||
        !strstr(agglo_last_error(), "cell 7") ||
        !strstr(agglo_last_error(), "number_density"))
      failures++;
    in = input_of(&cells[0], -1.0);
    status = agglo_cell_advance(coupling, 8, 0, &in, &state, &out);
    printf("bad dt: status %d: %s\n", (int)status, agglo_last_error());
    if (status != AGGLO_STATUS_INPUT || !strstr(agglo_last_error(), "dt")) failures++;
  }

  for (int i = 0; i < CELLS; i++) {
    agglo_output_free(outs[i]);
    agglo_state_free(states[i]);
  }
  agglo_coupling_free(coupling);
  printf(failures ? "FAILED: %d checks\n" : "all checks hold\n", failures);
  return failures ? 1 : 0;
}
