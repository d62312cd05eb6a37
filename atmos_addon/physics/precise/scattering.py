# SPDX-License-Identifier: GPL-3.0-or-later
"""Multiple scattering (:class:`MultipleScatteringTable`, per atmosphere).

The light that has scattered at least once, per unit sun irradiance above the atmosphere, at every altitude h
and sun zenith cosine mu_s, and what a view ray in-scatters of it (Hillaire 2020, "A Scalable and Production
Ready Sky and Atmosphere Rendering Technique", section 5.5, extended as below).

Nodes: altitudes h_j = top (j / (n - 1))^2 and the sun zenith cosines of ``sun_nodes.SunCosineNodes`` (mu_s = 0 is a
node and they crowd at the terminator: 32 linear samples would interpolate the blue hour's light, which falls by
orders of magnitude within a few degrees of sun below the horizon, across one cell, 1.5x too bright on average at a
sun 4 deg down; above 23 deg they are even in the sun's elevation). From each node rays in 2
:data:`DIRECTION_ZENITHS` x :data:`DIRECTION_AZIMUTHS` directions w (``directions.direction_grid``: Gauss-Legendre
in each hemisphere, even azimuths symmetric about the sun's; solid angles dOmega) are marched in :data:`MARCH_STEPS`
steps to the ground or the top (``rays.march_rays``), t = length u^2 with u at the steps' middles (crowded at the
node, where the air is densest for the rays that climb), p the point at distance t, where the sun has zenith cosine
mu_s(p), up_p and sun_p its local zenith and horizontal toward the sun.

The haze's Henyey-Greenstein phase function is split the delta-Eddington way (``directions.forward_fraction``): f = g^2
of its scattering (g > 0; none for a haze scattering backward) is a delta function forward (light that goes on as
if not scattered) and the rest scatters with mean cosine g' = (g - f) / (1 - f). So along the rays T' is the
transmittance with the haze's extinction less f beta_M n_M, sigma_s' = beta_R n_R + (1 - f) beta_M n_M the
scattering that turns light. The first two orders are carried by direction, the rest as a P1 field:

* The first order, by direction: the sun's beam (true transmittance T_sun) scattered with the true phase functions,
  carried to x with T_c, the transmittance less only the part of the haze's peak the direction grid cannot
  resolve, f_c (``directions.grid_forward_fraction``: the peak above its value at the channel's cut,
  ``directions.grid_cut_deg``):

    L_1(x, w) = integral T_c (beta_R n_R Phi_R + beta_M n_M Phi_HG)(w . sun) T_sun dt
                + T_c,g T_sun mu_s,g albedo / pi

* The second, by direction: L_1 at the nodes in-scattered with the phase functions on the direction grid
  (S_1, the haze's with its cone of f_c taken out, (1 - f_c) Phi_c: ``directions.view_weights``), read at each step's
  point for the direction it looks along (linearly between the nodes), and carried with T':

    L_2(x, w) = integral T' (beta_R n_R S_1R + beta_M n_M S_1M)(p, w) dt + T'_g albedo E_1(ground point) / pi

  with E_1 the ground's irradiance from L_1. The second order is not left to the P1 field: a field as peaked as
  the haze's light around a low sun (its aureole) is far from J + 3 H . w, and the delta cut, which keeps all of
  the peak on the sun's line, leaves the light of a Martian sunset 1.13x too bright toward the sun and 0.97x
  away (0.9x in blue). With the whole peak resolved (f_c = 0) the grid spreads the aureole over its 22.5 deg
  cells: the Martian sunset within 3 % but an Earth sunset's red toward the sun 0.8-0.87x and the blue hour 9 %.
  Swept over 0-45 deg (docs/quality.md), a cut of 20-35 deg between the two improves every low-sun case.
* The third and higher orders: at every node the light of the second and higher orders is described by its mean
  radiance J and its first moment H = (1 / 4 pi) integral L w dOmega (two components, up and toward the sun: the
  light is symmetric about the sun's plane), the P1 field L(w) ~ J + 3 H . w, and a point that scatters it sends
  J sigma_s' + 3 (g - f) beta_M n_M H . w back along w (Rayleigh's mean cosine is 0). With Q(p, w) that emission,
  read off the nodes bilinearly, and the Lambertian ground of ``ground_albedo`` lit by the sky's irradiance E
  (from the same field over the upper hemisphere):

    (J, H)(x) = (1 / 4 pi) sum_w (1, w) [L_2(x, w) + integral T' Q(p, w) dt + T'_g albedo E(ground point) / pi]
                dOmega

  is linear in the nodes' (J, H): one linear solve, (I - A) X = X_2, over 3 unknowns per node and channel
  (:attr:`MultipleScatteringTable.psi` and ``first_moment`` add the first order's J and H).

The radiance field by direction is then

    L(x, w) = L_1(x, w) + L_2(x, w) + integral T' Q(p, w) dt + T'_g albedo E(ground point) / pi,

and a view ray looking along v in-scatters it with the true phase functions at its own point (the light arriving
from w is scattered by the angle whose cosine is w . v):

    S_i(x, v) = sum_w Phi_i(w . v) L(x, w) dOmega,      in-scattering sigma_R S_R + sigma_M S_M,

tabulated over v's zenith cosine and its azimuth from the sun (:meth:`MultipleScatteringTable.scattered`; the phase
weights of each v averaged over the grid's cells and normalised to sum to 1, ``directions.cell_weights``, so the
sharp forward peak of the haze neither gains nor loses light between the directions). So the second order seen by
the camera is exact up to the direction sampling, the third up to the sampling and the cone f_c; the fourth and
higher are a P1 field at their last-but-one point.

Measured against the complete reference (``tools/bench_accuracy.py``, Monte Carlo, every order; worst pixel
luminance error, docs/quality.md): at 4000 paths by day 1.1-2.0 %; against more paths the blue hour 3.8 % (xy
0.0093) and the Martian sunset 3.7 % (xy 0.0058) at 192 000 (two seeds), the overcast 1 deg sun 2.9 % at 96 000
(its reference's noise 1.1-1.4 % a ray), Mars at noon 0.4 % at 64 000. The simpler schemes it improves on, at
4000 paths:

* Hillaire 2020's Psi_ms = L_2 / (1 - f_ms), in-scattered isotropically: his series assumes the higher orders
  at x are those of a medium lit everywhere like x (A J ~ f_ms J(x)), which misses the light that enters a thick
  haze from the lit sky above and diffuses down to where the sun no longer reaches. By day 1.2-6.9 %, the
  sunsets 19 % / 31 %, blue hour 68 %, overcast 1 deg sun 82 %, Mars sunset 81 %.
* Every order carried between the nodes as an isotropic mean radiance (J alone, the true extinction): by day
  1.1-3.0 %, the sunsets 5.4 % / 6.6 %, Mars noon 9.7 %, blue hour 23 %, overcast 34 %, Mars sunset 39 %. An
  isotropic third order cannot hold that the light of a forward-scattering haze at a low sun keeps travelling
  away from the sun: the overcast 0.6-0.8x the reference, Mars at sunset 0.6x toward the sun and 1.2-1.9x away.
* The first moment and the delta-Eddington split from the second order on (the second order a P1 field too): by
  day 1.1-2.1 %, the sunsets 1.7 % / 1.6 %, Mars noon 5.5 %, overcast 4.5 %, blue hour 8.7 %, Mars sunset 18 %.
  The first moment alone (the true phase function's g, no delta cut) swings Mars the other way (0.3-0.4x away
  from the sun in blue: a P1 field of a peaked phase function goes negative behind it) and leaves the overcast
  0.85-0.95x; the delta cut alone (f = g, an isotropic rest) 1.2-1.6x too bright.

What the sun-cosine nodes and the forward cut per channel gain is measured in ``sun_nodes.SunCosineNodes`` and
``directions.grid_cut_deg``.

The directions, steps and view grid are the bench's choice (more directions change no day case by over 0.5 % and the
low suns by a few %); 24 altitudes and 16 steps (32 and 24 take twice the build for the same errors within 0.12
point, the overcast's aside: 5.7 % against 4.5 %, with the second order a P1 field). Cost, on this project's 2-core
machine, with the sun table: 1.07-1.11 s (1.54-1.71 s on one thread; ``tools/bench_tables.py``; 0.88-0.96 s without
the second order by direction). The light is symmetric about the sun's plane, so only the half of the directions
with w_y > 0 is marched and the other half mirrored (the same numbers for half the work: 4 s -> 2.7 s with J alone);
the orders are summed by GMRES (``solver.solve_orders``, 0.02-0.03 s a channel where LU took 0.35 s: 4.0 -> 2.4 s);
the altitudes' rows are built on ``parallel.WORKERS`` threads (at 32 altitudes and 24 steps 2.3-2.4 s on one thread,
1.4-1.6 s on 2 cores; the same numbers to the bit). Where the time goes (one thread, 1.54-1.71 s in that bench): the
transport matrix's rows, 27 weighted bincounts per altitude (0.57 s under cProfile; ``np.add.at`` and a sorted
``reduceat`` take 2.6-2.8x as long, batched matrix products over each altitude cell's points 1.6x), the lookups 0.4
s, the march 0.15 s.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..atmosphere import Atmosphere
from ..phase import phase_hg, phase_rayleigh
from . import solver
from .directions import MarchedHalf, marched_half, mie_g, view_weights
from .interpolation import bilinear, linear_then_log_linear, log_linear, table_cell
from .parallel import in_parallel
from .rays import MOMENTS, Rays, RayFan, emission, march_rays, ray_fan
from .sun_nodes import SunCosineNodes
from .transmittance import SunTransmittanceTable

#: Ground albedo of the multiple-scattering table when none is given (a grey, green-ish land).
DEFAULT_GROUND_ALBEDO = (0.18, 0.2, 0.15)
#: The direction grid (``directions.direction_grid``): Gauss-Legendre zenith cosines per hemisphere, and azimuths.
DIRECTION_ZENITHS = 6
DIRECTION_AZIMUTHS = 16
#: Steps along each marched ray (``rays.march_rays``).
MARCH_STEPS = 16
#: The view grid S_R and S_M are tabulated on: zenith cosines even in -1 .. 1, azimuths from the sun's even in 0 .. pi.
VIEW_COSINES = 17
VIEW_AZIMUTHS = 9


class MultipleScatteringTable:
    """Psi_ms, its first moment and the in-scattering S_R, S_M of an atmosphere at every altitude and sun zenith
    cosine (the module docstring): built at ``n_altitudes`` altitudes h_j = top (j / (n - 1))^2 and the sun cosines
    of ``SunCosineNodes(n_cosines)``, with the Lambertian ground of ``ground_albedo`` (3,) and ``sun_table``'s
    transmittance to the sun.

    The build, in order (each step a method): march the rays from every node and scatter the sun's light once along
    them, which also gives the rows of the transport matrix A (:meth:`_march_first_order`); scatter that light once
    more by direction (:meth:`_scatter_first_order_again`); solve for the third and higher orders' J and H
    (:meth:`_solve_higher_orders`); gather them by direction (:meth:`_gather_higher_orders`); tabulate what a view ray
    in-scatters of the field (:meth:`_view_table`).
    """

    def __init__(self, atm: Atmosphere, sun_table: SunTransmittanceTable, ground_albedo=DEFAULT_GROUND_ALBEDO,
                 n_altitudes: int = 24, n_cosines: int = 33) -> None:
        self.atm = atm
        #: The sun transmittance the table is built with.
        self.sun_table = sun_table
        #: Where the sun cosines' nodes lie (crowded at the terminator, mu_s = 0, where the light changes fastest).
        self.sun_nodes = SunCosineNodes(n_cosines)
        self.n_alt, self.n_mu = n_altitudes, len(self.sun_nodes)
        self.n_view_z, self.n_view_a = VIEW_COSINES, VIEW_AZIMUTHS
        half = marched_half(DIRECTION_ZENITHS, DIRECTION_AZIMUTHS)
        fan = ray_fan(half.directions, self.sun_nodes.cosines, MARCH_STEPS, np.asarray(ground_albedo, np.float64))
        # What the three unknowns of a node (J, H_up, H_sun) take of the light arriving at it along w: 1, w_up, w_sun
        # (x's frame: z up, the sun in the x-z plane toward +x), times dOmega / 4 pi.
        weighting = np.stack([np.ones(len(half.directions)), half.directions[:, 2], half.directions[:, 0]]
                             ) * half.share[:, 0]                                  # (3, D)
        altitudes = atm.atmosphere_height * np.linspace(0.0, 1.0, n_altitudes) ** 2
        all_rays = [march_rays(atm, fan, float(altitude)) for altitude in altitudes]
        _, weights_r, weights_m, weights_cut = view_weights(DIRECTION_ZENITHS, DIRECTION_AZIMUTHS, VIEW_COSINES,
                                                            VIEW_AZIMUTHS, tuple(mie_g(atm)))

        once, transport, ground_rows, sky_once, sky_more = self._march_first_order(all_rays, fan, half, weighting)
        first_rows = self._view_table(once, half, weights_r, weights_cut)[1]
        second = self._scatter_first_order_again(all_rays, first_rows, sky_once)
        sky_second = np.einsum("mdc,d->mc", second[0], half.upward)                # E_2 at the ground, (M_g, 3)
        solved = self._solve_higher_orders(second, sky_second, transport, ground_rows, sky_more, weighting)
        del transport                              # its 240 MB freed before the field is gathered

        higher = solved.reshape(MOMENTS, self.n_alt, self.n_mu, 3)                 # J, H of every order from the 2nd
        once_moments = np.einsum("jmdc,ad->ajmc", once, weighting)                 # J_1, H_1 (3, J, M, 3)
        moments = once_moments + higher
        #: Psi_ms (altitudes, sun cosines, 3): the mean radiance of light scattered at least once, 1/sr per unit E_top.
        self.psi = np.maximum(moments[0], 0.0)
        #: H (altitudes, sun cosines, 2, 3): its first moment (1 / 4 pi) integral L w dOmega, along the local zenith and
        #: the horizontal toward the sun, 1/sr per unit E_top.
        self.first_moment = np.moveaxis(moments[1:], 0, 2).copy()
        #: J_1 (altitudes, sun cosines, 3): the mean radiance of light scattered exactly once.
        self.single = once_moments[0]
        sky_irradiance = sky_second + np.einsum("cgn,nc->gc", sky_more, solved)    # E_2 + E_B at the ground
        field = once + second
        self._gather_higher_orders(all_rays, field, higher, sky_irradiance)
        #: S_R and S_M (altitudes, sun cosines, view cosines, view azimuths, 2, 3), flattened to (nodes, 6) rows;
        #: float32, half the memory read. The view ray scatters with the true phase functions.
        self.in_scattering, self._with_next_cosine = self._view_table(field, half, weights_r, weights_m)

    def _march_first_order(self, all_rays: list[Rays], fan: RayFan, half: MarchedHalf, weighting: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, list, np.ndarray, np.ndarray]:
        """(L_1 (altitudes, sun cosines, D, 3) by marched direction, A without the ground's light (3 channels, 3N,
        3N), the ground points' rows per altitude (3 out, 3 channels, M, M_g), E_1 at the ground (M_g, 3), and the
        ground's irradiance from the nodes' unknowns (3 channels, M_g, 3N)): each altitude's rays, on the threads.

            L_1(x, w) = integral T_c (beta_R n_R Phi_R + beta_M n_M Phi_HG)(w . sun) T_sun dt
                        + T_c,g T_sun mu_s,g albedo / pi"""
        sun_table, n_cosines = self.sun_table, self.n_mu
        n_nodes = self.n_alt * n_cosines
        phase_r = phase_rayleigh(fan.along)[:, :, None, None]                      # (M, D, 1, 1)
        phase_m = phase_hg(fan.along, self.atm.mie_g)[:, :, None, :]               # (M, D, 1, 3)
        once = np.zeros((self.n_alt, n_cosines, len(half.directions), 3))         # L_1(x, w)
        transport = np.zeros((3, MOMENTS * n_nodes, MOMENTS * n_nodes))            # A per channel
        ground_rows = [None] * self.n_alt     # per altitude: the ground points' weights on the ground's sun cosines
        sky = {}

        def march(j: int) -> None:             # the rows of altitude j's nodes: each call writes its own slices
            rays = all_rays[j]
            t_sun = sun_table(rays.radius_m, rays.sun_cosine)                      # (M, D, S, 3)
            light = np.sum(t_sun * (rays.first_rayleigh[None] * phase_r + rays.first_mie[None] * phase_m), axis=2)
            lit_ground = np.maximum(rays.ground_sun_cosine, 0.0)[..., None] * sun_table(
                rays.ground_radius_m + 1e-3, rays.ground_sun_cosine)
            once[j] = light + (rays.first_to_ground / np.pi)[None] * lit_ground
            emitted = emission(self.atm, rays)                                     # (3, M, D, S, 3)
            # (out a, in b): sum over w of project_a(w) dOmega / 4 pi times what the steps along w send of b
            weights = emitted[None] * weighting[:, None, None, :, None, None]
            blocks = self._matrix_rows(rays.altitude_m, rays.sun_cosine, weights)   # (3, 3, 3, M, N)
            for a in range(MOMENTS):
                transport[:, a * n_nodes + j * n_cosines:a * n_nodes + (j + 1) * n_cosines] = np.concatenate(
                    list(blocks[a]), axis=-1)
            ground = self._matrix_rows(np.zeros(()), rays.ground_sun_cosine,
                                       rays.to_ground[None, None] * (weighting / np.pi)[:, None, :, None])
            ground_rows[j] = ground[..., :n_cosines]                                # (3 out, 3 ch, M, M_g)
            if j == 0:   # the ground's irradiance from the sky: E_1 of the once-scattered light, and E_B of the rest
                sky["once"] = np.einsum("mdc,d->mc", light, half.upward)            # (M_g, 3)
                sky["more"] = np.concatenate(list(self._matrix_rows(
                    rays.altitude_m, rays.sun_cosine, emitted * half.upward[None, None, :, None, None])),
                    axis=-1)                                                        # (3, M_g, 3N)

        in_parallel(march, self.n_alt)
        return once, transport, ground_rows, sky["once"], sky["more"]

    def _scatter_first_order_again(self, all_rays: list[Rays], first_rows: np.ndarray, sky_once: np.ndarray
                                   ) -> np.ndarray:
        """L_2 (altitudes, sun cosines, D, 3): the first order scattered once more, by direction,

            L_2(x, w) = integral T' (beta_R n_R S_1R + beta_M n_M S_1M)(p, w) dt + T'_g albedo E_1 / pi,

        S_1 the in-scattering of L_1 with the haze's forward cone taken out (``first_rows``, laid out as
        :attr:`_with_next_cosine`), read at each step's point for the direction it looks along."""
        second = np.zeros((self.n_alt, self.n_mu) + all_rays[0].to_ground.shape)

        def scatter_once(j: int) -> None:
            rays = all_rays[j]
            mu = rays.sun_cosine
            up = np.broadcast_to(rays.view_up[None], mu.shape)
            # linear between the sun-cosine nodes (log-linearly, against 192 000 reference paths, the blue hour is
            # 3.8 % and xy 0.0102 against 3.8 % and 0.0093, the Martian sunset 5.4 % against 5.6 % with a 30 deg cut
            # for every channel; the overcast 3.1 % against 2.6 % at 96 000)
            s_r, s_m = self._lookup(first_rows, np.broadcast_to(rays.altitude_m, mu.shape), mu, up, rays.toward_sun,
                                    geometric=False)
            second[j] = np.sum(rays.step_rayleigh[None] * s_r + rays.step_mie[None] * s_m, axis=2)
            second[j] += self._ground_light(rays, sky_once)

        in_parallel(scatter_once, self.n_alt)
        return second

    def _solve_higher_orders(self, second: np.ndarray, sky_second: np.ndarray, transport: np.ndarray,
                             ground_rows: list, sky_more: np.ndarray, weighting: np.ndarray) -> np.ndarray:
        """The nodes' (J, H) of the second and higher orders (3N, 3 channels): (I - A) X = X_2, X_2 the second
        order's moments plus the ground's reflection of its irradiance E_2 (``sky_second``). The ground reflects the
        sky's light as a Lambertian surface: radiance albedo / pi E, E from the upper hemisphere (not J at the ground,
        whose mean over every direction would count the ground's own light); its rows join A here."""
        n_nodes = self.n_alt * self.n_mu
        second_moments = np.einsum("jmdc,ad->ajmc", second, weighting)
        reflected = [np.concatenate([np.einsum("cmg,gc->mc", rows[a], sky_second) for rows in ground_rows])
                     for a in range(MOMENTS)]                                       # the ground's E_2, reflected
        source = np.concatenate([second_moments[a].reshape(n_nodes, 3) + reflected[a]
                                 for a in range(MOMENTS)])                          # (3N, 3): J_2, H_2
        for a in range(MOMENTS):                  # (3 ch, N, M_g) @ (3 ch, M_g, 3N): one batched product
            transport[:, a * n_nodes:(a + 1) * n_nodes] += np.concatenate(
                [rows[a] for rows in ground_rows], axis=1) @ sky_more
        return np.stack([solver.solve_orders(transport[ch], source[:, ch]) for ch in range(3)], axis=-1)

    def _gather_higher_orders(self, all_rays: list[Rays], field: np.ndarray, higher: np.ndarray,
                              sky_irradiance: np.ndarray) -> None:
        """Add the third and higher orders to ``field`` (L_1 + L_2 by marched direction) at every node:
        integral T' Q(p, w) dt + T'_g albedo E(ground point) / pi, Q read off the nodes' J and H.

        Between sun-cosine nodes the higher orders' J is read log-linearly (it falls by orders of magnitude across
        the terminator) and H as J times the interpolated H / J, which changes slowly; |H| <= J for any radiance
        field that is nowhere negative, which bounds the ratio where J is the solve's rounding."""
        n_altitudes, n_cosines = self.n_alt, self.n_mu
        higher_mean = np.maximum(higher[0], 0.0)
        mean = np.broadcast_to(higher[0][:, :, None], (n_altitudes, n_cosines, 2, 3))
        anisotropy = np.clip(np.divide(np.moveaxis(higher[1:], 0, 2), mean, out=np.zeros_like(mean),
                                       where=mean > 0.0), -1.0, 1.0).reshape(n_altitudes, n_cosines, 6)

        def gather(j: int) -> None:            # + the third and higher orders by direction, at altitude j's nodes
            rays = all_rays[j]
            emitted = emission(self.atm, rays)
            altitude_m = np.broadcast_to(rays.altitude_m, rays.sun_cosine.shape)
            i, k = self._indices(altitude_m, rays.sun_cosine)
            shape = bilinear(anisotropy, i, k).reshape(i.shape + (2, 3))           # H / J, linear
            field[j] += np.sum(linear_then_log_linear(higher_mean, i, k)            # J, log-linear in the sun
                               * (emitted[0] + emitted[1] * shape[..., 0, :] + emitted[2] * shape[..., 1, :]), axis=2)
            field[j] += self._ground_light(rays, sky_irradiance)

        in_parallel(gather, n_altitudes)

    def _view_table(self, field: np.ndarray, half: MarchedHalf, rayleigh_weights: np.ndarray,
                    haze_weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(S_R and S_M as (nodes, 6) rows, float32; the same beside the next sun cosine's, as
        :attr:`_with_next_cosine`) of a field by marched direction (altitudes, sun cosines, D, 3), scattered into
        each view direction with the weights of ``directions.view_weights``."""
        view_shape = (self.n_alt, self.n_mu, VIEW_COSINES, VIEW_AZIMUTHS, 3)
        field = field[:, :, half.mirror]                                            # every direction of the grid
        rayleigh = np.stack([field[..., ch] @ rayleigh_weights.T for ch in range(3)], axis=-1)     # (J, M, V, 3)
        mie = np.stack([field[..., ch] @ haze_weights[..., ch].T for ch in range(3)], axis=-1)
        # Not below 0: a P1 field can dip below it behind a peaked phase function, by under 1e-5 of the table's
        # largest value (measured: a backward haze g -0.999, Mars' dust 30x at g 0.99).
        rows = np.maximum(np.stack([rayleigh.reshape(view_shape), mie.reshape(view_shape)],
                                   axis=-2).reshape(-1, 6), 0.0).astype(np.float32)
        # Each row beside the same node at the next sun cosine (zeros past the last, which no lookup reaches), so
        # :meth:`_lookup` reads both sun-cosine nodes of a corner in one gather.
        step = VIEW_COSINES * VIEW_AZIMUTHS
        return rows, np.concatenate([rows, np.concatenate([rows[step:], np.zeros((step, 6), np.float32)])], axis=1)

    def _ground_light(self, rays: Rays, irradiance: np.ndarray) -> np.ndarray:
        """(M, D, 3): T'_g albedo E / pi, what the Lambertian ground sends back along each ray that meets it, E
        (the ground's sun cosines, 3) read at the ray's end."""
        _, k = self._indices(0.0, rays.ground_sun_cosine)
        lit = np.stack([np.interp(k, np.arange(self.n_mu), irradiance[:, ch]) for ch in range(3)], axis=-1)
        return rays.to_ground[None] / np.pi * lit

    def _indices(self, altitude_m: ArrayLike, cos_zenith: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Fractional node indices (altitude row, sun-cosine column) of points, as :meth:`__call__` reads them."""
        altitude = np.clip(np.asarray(altitude_m, dtype=np.float64), 0.0, self.atm.atmosphere_height)
        i = np.sqrt(altitude / self.atm.atmosphere_height) * (self.n_alt - 1)
        return i, self.sun_nodes.index(cos_zenith)

    def _matrix_rows(self, altitude_m: np.ndarray, cos_zenith: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """Rows of A for one altitude's M nodes, (..., 3 channels, M, nodes), from points of shape (M, ...) (the
        altitude broadcast to it) with weights (..., M, ..., 3): each point adds its weight times the bilinear weight
        of each of the four nodes around it (the matrix form of J(point) read off the nodes), one bincount per
        leading index and channel."""
        i, k = self._indices(np.broadcast_to(altitude_m, np.shape(cos_zenith)), cos_zenith)
        i0, k0, fi, fk = table_cell(self.n_alt, self.n_mu, i, k)
        n_rows, n_nodes = i.shape[0], self.n_alt * self.n_mu
        row = np.arange(n_rows).reshape((-1,) + (1,) * (i.ndim - 1)) * n_nodes
        flat = np.concatenate([(row + (i0 + di) * self.n_mu + (k0 + dk)).ravel() for di in (0, 1) for dk in (0, 1)])
        corner = np.concatenate([(wi * wk).ravel() for wi in (1.0 - fi, fi) for wk in (1.0 - fk, fk)])
        lead = weights.shape[:-1 - i.ndim]
        columns = np.moveaxis(np.broadcast_to(weights, lead + i.shape + (3,)), -1, len(lead))
        columns = columns.reshape(-1, i.size)                                       # (lead x 3, points)
        corners = corner.reshape(4, -1)                                             # (4 corners, points)
        result = np.stack([np.bincount(flat, weights=(corners * column).ravel(), minlength=n_rows * n_nodes)
                           for column in columns])
        return result.reshape(lead + (3, n_rows, n_nodes))

    def __call__(self, altitude_m: ArrayLike, cos_zenith: ArrayLike) -> np.ndarray:
        """Psi_ms at altitude ``altitude_m`` (m, clamped to the atmosphere) and sun zenith cosine, (..., 3):
        linear in altitude, log-linear in the sun cosine as :meth:`scattered` (so that the mean of S_i over every
        view is Psi_ms between the nodes too)."""
        i, k = self._indices(altitude_m, cos_zenith)
        return linear_then_log_linear(self.psi, i, k)

    def scattered(self, altitude_m: ArrayLike, cos_zenith: ArrayLike, view_cos_zenith: ArrayLike,
                  view_toward_sun: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(S_R, S_M), each (..., 3): what a view ray in-scatters of the multiply scattered light per unit Rayleigh and
        Mie scattering coefficient, 1/sr per unit E_top, at altitude ``altitude_m`` (m) with the sun at zenith cosine
        ``cos_zenith``, for a view direction v with local zenith cosine ``view_cos_zenith`` and component
        ``view_toward_sun`` along the horizontal direction to the sun (v . x_sun; arrays that broadcast).

        Interpolated linearly in altitude and the two view coordinates at the two sun-cosine nodes around the point,
        then log-linearly (geometrically) between them: across the terminator the light falls by orders of
        magnitude within a few degrees of sun, roughly exponentially, so a straight line between two nodes lies far
        above it. Measured on the clear preset's sky seen from the ground (5 deg up, away from the sun;
        ``MultipleScatteringTable`` built with 257 sun cosines as the converged value): linear interpolation on the
        33 nodes was 1.30x too bright at a sun 4 deg below the horizon and 1.42x at 6 deg (the spectral reference's
        +27 % and +50 %, docs/reference_sky.md), log-linear 0.96x and 0.99x (the zenith 0.99x and 1.00x, from 1.05x
        and 1.11x); by day the two differ by under 0.3 %. Where either node is 0 (no light at all) the
        interpolation is linear."""
        return self._lookup(self._with_next_cosine, altitude_m, cos_zenith, view_cos_zenith, view_toward_sun)

    def _lookup(self, table: np.ndarray, altitude_m: ArrayLike, cos_zenith: ArrayLike, view_cos_zenith: ArrayLike,
                view_toward_sun: ArrayLike, *, geometric: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`scattered` of a ``table`` laid out as :attr:`_with_next_cosine`; between the sun-cosine nodes
        log-linear (``geometric``), or linear."""
        i, k = self._indices(altitude_m, cos_zenith)
        vz = np.clip(np.asarray(view_cos_zenith, dtype=np.float64), -1.0, 1.0)
        across = np.sqrt(np.maximum(1.0 - vz * vz, 1e-12))
        azimuth = np.arccos(np.clip(np.asarray(view_toward_sun, dtype=np.float64) / across, -1.0, 1.0))
        coords = np.broadcast_arrays(i, k, (vz + 1.0) * 0.5 * (self.n_view_z - 1),
                                     azimuth * ((self.n_view_a - 1) / np.pi))
        sizes = (self.n_alt, self.n_mu, self.n_view_z, self.n_view_a)
        strides = (sizes[1] * sizes[2] * sizes[3], sizes[2] * sizes[3], sizes[3], 1)
        base, pairs = 0, []
        for x, n, stride in zip(coords, sizes, strides):
            low = np.clip(np.floor(x).astype(np.int64), 0, n - 2)
            fraction = np.clip(x - low, 0.0, 1.0).astype(np.float32)
            base = base + low * stride
            pairs.append((1.0 - fraction, fraction))
        # linear in altitude and the view at the two sun-cosine nodes around the point (8 corners, each row holding
        # both nodes), then (log-)linear between the two; in float32, the table's own precision (float64 changed the
        # tiles by under 5e-7 relative and took twice the time)
        second = [[a * b for b in pairs[3]] for a in pairs[2]]
        both = np.zeros(coords[0].shape + (12,), np.float32)
        for corner in range(8):
            bits = [(corner >> axis) & 1 for axis in range(3)]
            row = base + bits[0] * strides[0] + bits[1] * strides[2] + bits[2] * strides[3]
            rows = np.take(table, row, axis=0)      # np.take: half the time of [row] here
            rows *= (pairs[0][bits[0]] * second[bits[1]][bits[2]])[..., None]
            both += rows
        fraction = pairs[1][1][..., None]
        if geometric:
            result = log_linear(both[..., :6], both[..., 6:], fraction).astype(np.float64)
        else:
            result = (both[..., :6] + fraction * (both[..., 6:] - both[..., :6])).astype(np.float64)
        return result[..., :3], result[..., 3:]
