/*
 * The shortest use of agglo from C: one flow-solver cell of monomers (one size class
 * of single grains, one of everything larger), advanced over three macro steps, the
 * number rates applied to the cell's densities between them. The long example with a
 * batch, restarts and refusals is advance_cells.c.
 *
 * Build (from the repository root, after `cargo build -p agglo-capi`):
 *   cc -std=c99 -Icapi/include capi/examples/one_cell.c -Ltarget/debug -lagglo_c \
 *      -Wl,-rpath,$PWD/target/debug -o one_cell
 *   ./one_cell scenarios/ballistic_aggregation.json
 */
#include <stdio.h>

#include "agglo.h"

#define CLASSES 2

/* Print the library's message and give up when a call fails. */
#define CHECK(call)                                                      \
  do {                                                                   \
    if ((call) != AGGLO_STATUS_OK) {                                     \
      fprintf(stderr, "%s: %s\n", #call, agglo_last_error());            \
      return 1;                                                          \
    }                                                                    \
  } while (0)

int main(int argc, char **argv) {
  if (argc != 2) return 2;
  double b0, m0; /* the primary grain's radius [m] and mass [kg] */
  CHECK(agglo_scenario_primary_load(argv[1], &b0, &m0));
  double edges[CLASSES + 1] = {0.5 * m0, 1.5 * m0, 1e9 * m0}; /* [kg] */
  AggloCouplingOptions options = agglo_coupling_options_default();
  options.bodies = 300;
  AggloCoupling *coupling = NULL;
  CHECK(agglo_coupling_load(argv[1], edges, CLASSES + 1, &options, &coupling));

  /* Monomers at a volume fraction of 5 %, at rest on average, 1 m^2/s^2 of agitation. */
  double n[CLASSES] = {0.05 / (4.0 / 3.0 * 3.14159265358979 * b0 * b0 * b0), 0.0};
  double m[CLASSES] = {m0, 2.0 * m0}, v[3 * CLASSES] = {0};
  double theta[CLASSES] = {300.0, 300.0}, tg[CLASSES] = {1.0, 1.0};
  AggloCellInput in = {n, m, v, theta, tg, NULL, {{0, 0, 0}, 300.0, AGGLO_DRAG_NONE, 0, 0},
                       2e-4};

  AggloCellState *state = NULL; /* NULL: lift the first step's bodies from the input */
  for (uint64_t step = 0; step < 3; step++) {
    AggloOutput *out = NULL;
    CHECK(agglo_cell_advance(coupling, 7, step, &in, &state, &out));
    double rate[CLASSES], se[CLASSES];
    CHECK(agglo_output_get(out, "number_rate", rate, se, CLASSES));
    printf("step %d: dn/dt = %.3e +- %.1e (monomers), %.3e +- %.1e (larger) 1/(m^3 s)\n",
           (int)step, rate[0], se[0], rate[1], se[1]);
    for (int k = 0; k < CLASSES; k++) n[k] += in.dt * rate[k];
    agglo_output_free(out);
    if (!(rate[0] < 0.0 && rate[1] > 0.0)) {
      fprintf(stderr, "monomers should stick into larger bodies\n");
      return 1;
    }
  }
  agglo_state_free(state);
  agglo_coupling_free(coupling);
  printf("done\n");
  return 0;
}
