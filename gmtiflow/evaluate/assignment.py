"""Gated global nearest-neighbour assignment (one ``linear_sum_assignment`` per call).

Rows (tracks) may stay unassigned: the cost matrix is augmented with one private "miss" column per
row whose cost is the gate, so a pair is only chosen when its cost is below the gate and when
assigning it lowers the total cost (Blackman & Popoli 1999, §6.5; the usual GNN formulation).
Pairs outside the gate get a cost larger than any gated solution and are never returned.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linear_sum_assignment

from gmtiflow.evaluate.order import dense_ids, small_key_order


def gated_assignment(cost: np.ndarray, gate: float):
    """Optimal one-to-one assignment of rows to columns with cost < ``gate``.

    Returns ``(rows, cols)``, integer arrays of the assigned pairs, sorted by row.  Minimises the
    sum of assigned costs plus ``gate`` for every unassigned row.  Deterministic.
    """
    cost = np.asarray(cost, float)
    nr, nc = cost.shape
    empty = np.zeros(0, dtype=np.int64)
    if nr == 0 or nc == 0:
        return empty, empty
    inside = np.isfinite(cost) & (cost < gate)
    if not inside.any():
        return empty, empty
    # Only rows and columns with at least one gated pair take part (keeps the problem small).
    rows_in = np.flatnonzero(inside.any(axis=1))
    cols_in = np.flatnonzero(inside.any(axis=0))
    sub = cost[np.ix_(rows_in, cols_in)]
    sub_in = inside[np.ix_(rows_in, cols_in)]
    n = len(rows_in)
    big = float(gate) * (n + 1) + 1.0
    aug = np.full((n, len(cols_in) + n), big)
    aug[:, :len(cols_in)] = np.where(sub_in, sub, big)
    aug[np.arange(n), len(cols_in) + np.arange(n)] = gate
    r, c = linear_sum_assignment(aug)
    real = c < len(cols_in)
    r, c = r[real], c[real]
    keep = sub_in[r, c]
    return rows_in[r[keep]].astype(np.int64), cols_in[c[keep]].astype(np.int64)


#: Relative margin by which the best pair of a star component (one row or one column) must beat
#: the second best for it to be taken without ``linear_sum_assignment``: far above the solver's
#: rounding, so the solver would return that pair too; closer calls go to the solver.
_STAR_MARGIN = 1e-9

#: Up to this many pairs the connected components are found by a union-find in Python (cheaper
#: than building a scipy.sparse graph for a dwell's handful of pairs); above, by scipy.
_SMALL_GRAPH = 256

#: The augmented matrices of the components are built together in flat buffers of about this
#: many entries (8 MB of costs; a larger component alone): a few numpy calls per buffer instead
#: of a dozen per component (the 1,000-vehicle scene's OSPA has ~2,500 components above 1,024
#: entries, which were built one by one at ~30 us each).
_BUFFER_ENTRIES = 1 << 20


def _components(r_idx: np.ndarray, c_idx: np.ndarray, nr: int, nc: int):
    """Component label (0, 1, ...) of every row node (first ``nr``) and column node (next
    ``nc``) of the bipartite graph with edges ``(r_idx[i], c_idx[i])``; every node has an
    edge.  The numbering of the components is arbitrary (callers only group by it)."""
    if len(r_idx) > _SMALL_GRAPH:
        return _graph_components(r_idx, c_idx, nr, nc)
    parent = list(range(nr + nc))
    for a, b in zip(r_idx.tolist(), (c_idx + nr).tolist()):
        while parent[a] != a:
            a = parent[a]
        while parent[b] != b:
            b = parent[b]
        if a != b:
            parent[max(a, b)] = min(a, b)
    roots = []
    for x in range(nr + nc):
        y = x
        while parent[y] != y:
            y = parent[y]
        parent[x] = y
        roots.append(y)
    uniq, label = np.unique(np.asarray(roots, np.int64), return_inverse=True)
    return len(uniq), label


def _graph_components(r_idx: np.ndarray, c_idx: np.ndarray, nr: int, nc: int):
    """:func:`_components` by scipy, on the pairs that share a row or a column with another
    pair only: a pair alone on its row and its column (most of them, when the gate is tight)
    is a component of its own, labelled after the others."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    deg_r = np.bincount(r_idx, minlength=nr)
    deg_c = np.bincount(c_idx, minlength=nc)
    alone = (deg_r[r_idx] == 1) & (deg_c[c_idx] == 1)
    label = np.empty(nr + nc, np.int64)
    n_comp = 0
    linked = np.flatnonzero(~alone)
    if len(linked):
        rn, rl = dense_ids(r_idx[linked])
        cn, cl = dense_ids(c_idx[linked])
        n = len(rn) + len(cn)
        graph = coo_matrix((np.ones(len(linked)), (rl, len(rn) + cl)), shape=(n, n))
        n_comp, lab = connected_components(graph, directed=False)
        label[rn], label[nr + cn] = lab[:len(rn)], lab[len(rn):]
    single = np.flatnonzero(alone)
    label[r_idx[single]] = label[nr + c_idx[single]] = n_comp + np.arange(len(single))
    return n_comp + len(single), label


#: Up to this many pairs (a dwell's typical few dozen) :func:`sparse_gated_assignment` runs in
#: plain Python (:func:`_small_assignment`): numpy's per-call cost dominates there (measured on
#: the issue-18 scene's dwells: 0.7 vs 1.0 ms at 49-128 pairs, 2.4 vs 3.6 ms at 129-512).
_SMALL_PAIRS = 512


def _small_assignment(rows: list, cols: list, cost: list, gate: float):
    """:func:`sparse_gated_assignment` of a few pairs (Python lists), the same decisions made
    the same way: components by union-find, a single pair taken, a star's clear cheapest pair
    taken, every other component solved on the matrix :func:`gated_assignment` builds."""
    n_pairs = len(rows)
    if len(set(rows)) == n_pairs and len(set(cols)) == n_pairs:
        o = sorted(range(n_pairs), key=rows.__getitem__)
        return (np.array([rows[i] for i in o], np.int64),
                np.array([cols[i] for i in o], np.int64))
    comps = {}
    lo, hi_r, hi_c = min(min(rows), min(cols)), max(rows), max(cols)
    if lo >= 0 and hi_r + hi_c < 4096:     # small indices: a list of parents, nodes as ints
        off = hi_r + 1
        parent = list(range(off + hi_c + 1))
        for r, c in zip(rows, cols):
            while parent[r] != r:
                r = parent[r]
            c += off
            while parent[c] != c:
                c = parent[c]
            if r != c:
                parent[c] = r
        for i, r in enumerate(rows):
            while parent[r] != r:
                r = parent[r]
            comps.setdefault(r, []).append(i)
    else:
        parent = {}

        def root(x):
            while parent.setdefault(x, x) != x:
                x = parent[x]
            return x
        for r, c in zip(rows, cols):
            a, b = root((0, r)), root((1, c))
            if a != b:
                parent[b] = a
        for i, r in enumerate(rows):
            comps.setdefault(root((0, r)), []).append(i)
    out = []
    for idx in comps.values():
        if len(idx) == 1:
            out.append((rows[idx[0]], cols[idx[0]]))
            continue
        rs = sorted({rows[i] for i in idx})
        cs = sorted({cols[i] for i in idx})
        costs = [cost[i] for i in idx]
        if not all(math.isfinite(c) and c < gate for c in costs):   # out of the gate: general
            sub = np.full((len(rs), len(cs)), np.inf)
            rpos = {r: k for k, r in enumerate(rs)}
            cpos = {c: k for k, c in enumerate(cs)}
            for i in idx:
                sub[rpos[rows[i]], cpos[cols[i]]] = cost[i]
            a, b = gated_assignment(sub, gate)
            out.extend((rs[x], cs[y]) for x, y in zip(a.tolist(), b.tolist()))
            continue
        if len(rs) == 1 or len(cs) == 1:
            o = sorted(range(len(idx)), key=costs.__getitem__)
            best, second = costs[o[0]], costs[o[1]]
            scale = max(abs(best), abs(second), abs(gate))
            if second - best > _STAR_MARGIN * scale:
                out.append((rows[idx[o[0]]], cols[idx[o[0]]]))
                continue
        n, m = len(rs), len(cs)
        rpos = {r: k for k, r in enumerate(rs)}
        cpos = {c: k for k, c in enumerate(cs)}
        aug = np.full((n, m + n), gate * (n + 1) + 1.0)
        pair = set()
        for i in idx:
            aug[rpos[rows[i]], cpos[cols[i]]] = cost[i]
            pair.add((rpos[rows[i]], cpos[cols[i]]))
        diag = np.arange(n)
        aug[diag, m + diag] = gate
        _, picked = linear_sum_assignment(aug)
        out.extend((rs[x], cs[y]) for x, y in enumerate(picked.tolist())
                   if y < m and (x, y) in pair)
    out.sort()
    return (np.array([r for r, _ in out], np.int64), np.array([c for _, c in out], np.int64))


def sparse_gated_assignment(rows: np.ndarray, cols: np.ndarray, cost: np.ndarray, gate: float):
    """:func:`gated_assignment` of the pairs ``(rows[i], cols[i])`` with ``cost[i] < gate`` (every
    other pair outside the gate), solved per connected component of the pairs' graph: one pair
    alone is assigned at once, larger components go through :func:`gated_assignment` on their
    own rows and columns.  The optimum is the dense one (components share no gated pair, and
    the dense problem never takes an out-of-gate pair); cost linear in the pairs for sparse
    gates.  Returns ``(rows, cols)`` sorted by row.

    Speed (the result is the same): a *star* component (one row, or one column, all its pairs
    inside the gate) takes its cheapest pair, found for all stars at once, when it beats the
    second cheapest by a clear margin; the matrices :func:`gated_assignment` would build for the
    other components are built at once, from the pairs (no per-component ``np.unique``), and
    each is solved by one ``linear_sum_assignment``."""
    rows, cols = np.asarray(rows, np.int64), np.asarray(cols, np.int64)
    cost = np.asarray(cost, float)
    empty = np.zeros(0, np.int64)
    if not len(rows):
        return empty, empty
    if len(rows) <= _SMALL_PAIRS:
        return _small_assignment(rows.tolist(), cols.tolist(), cost.tolist(), float(gate))
    r_ids, r_idx = dense_ids(rows)
    c_ids, c_idx = dense_ids(cols)
    nr, nc = len(r_ids), len(c_ids)
    if nr == len(rows) and nc == len(cols):
        o = np.argsort(rows, kind="stable")      # every pair its own component
        return rows[o], cols[o]
    n_comp, label = _components(r_idx, c_idx, nr, nc)
    pair_label = label[r_idx]
    n_pairs = np.bincount(pair_label, minlength=n_comp)
    single = n_pairs[pair_label] == 1
    out_r, out_c = [r_idx[single]], [c_idx[single]]      # row / column nodes
    multi = np.flatnonzero(~single)
    if len(multi):
        comp_rows = np.bincount(label[:nr], minlength=n_comp)
        comp_cols = np.bincount(label[nr:], minlength=n_comp)
        inside = np.isfinite(cost) & (cost < gate)
        comp_out = np.bincount(pair_label, weights=~inside, minlength=n_comp) > 0
        # Stars whose pairs are all inside: the cheapest pair, when clearly the cheapest.
        star = ((comp_rows == 1) | (comp_cols == 1)) & ~comp_out
        solved = np.zeros(n_comp, bool)
        sp = multi[star[pair_label[multi]]]
        if len(sp):
            o = sp[np.lexsort((cost[sp], pair_label[sp]))]
            lab = pair_label[o]
            first = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
            best, second = cost[o[first]], cost[o[first + 1]]       # a star has >= 2 pairs
            scale = np.maximum(np.maximum(np.abs(best), np.abs(second)), abs(float(gate)))
            clear = second - best > _STAR_MARGIN * scale
            win = o[first[clear]]
            solved[lab[first[clear]]] = True
            out_r.append(r_idx[win])
            out_c.append(c_idx[win])
        rest = multi[~solved[pair_label[multi]]]
        if len(rest):
            r, c = _solve_components(rest, r_idx, c_idx, cost, label, pair_label, nr, nc,
                                     comp_rows, comp_cols, comp_out, float(gate))
            out_r.append(r)
            out_c.append(c)
    rr, cc = np.concatenate(out_r), np.concatenate(out_c)
    o = small_key_order(rr, nr)        # by row (r_ids increase with the node index)
    return r_ids[rr[o]], c_ids[cc[o]]


def _solve_components(pairs, r_idx, c_idx, cost, label, pair_label, nr, nc, comp_rows,
                      comp_cols, comp_out, gate):
    """The assigned (row node, column node) pairs of the components of ``pairs`` (pair indices),
    each solved as :func:`gated_assignment` solves it."""
    # Each component's rows and columns numbered in increasing index (as np.unique gives them
    # to gated_assignment), for all components at once.
    local_r = _local_index(label[:nr], r_idx[pairs])
    local_c = _local_index(label[nr:], c_idx[pairs])
    order = pairs[small_key_order(pair_label[pairs], len(comp_rows))]
    lab = pair_label[order]
    first = np.r_[0, np.flatnonzero(lab[1:] != lab[:-1]) + 1]
    comps = lab[first]
    out_r, out_c = [], []
    general = comp_out[comps]       # an out-of-gate pair: gated_assignment decides what is left
    if general.any():
        bounds = np.r_[first, len(order)]
        for k in np.flatnonzero(general).tolist():
            grp = order[bounds[k]:bounds[k + 1]]
            gr, ir = np.unique(r_idx[grp], return_inverse=True)
            gc, ic = np.unique(c_idx[grp], return_inverse=True)
            sub = np.full((len(gr), len(gc)), np.inf)
            sub[ir, ic] = cost[grp]
            a, b = gated_assignment(sub, gate)
            out_r.append(gr[a])
            out_c.append(gc[b])
        keep = ~general[np.searchsorted(comps, lab)]
        order, lab = order[keep], lab[keep]
        comps = comps[~general]
        first = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]]) if len(lab) else first[:0]
    if len(comps):
        # Buffers of whole components, each starting a new _BUFFER_ENTRIES-sized share of the
        # entries (a larger component ends its buffer); the pairs are grouped by component in
        # the order of comps.
        n, m = comp_rows[comps], comp_cols[comps]
        size = n * (m + n)
        part = (np.cumsum(size) - size) // _BUFFER_ENTRIES
        cut = np.r_[0, np.flatnonzero(part[1:] != part[:-1]) + 1, len(comps)]
        pair_cut = np.r_[first, len(order)][cut]
        for a, b, pa, pb in zip(cut[:-1].tolist(), cut[1:].tolist(), pair_cut[:-1].tolist(),
                                pair_cut[1:].tolist()):
            r, c = _solve_buffered(comps[a:b], order[pa:pb], lab[pa:pb], r_idx, c_idx, cost,
                                   local_r, local_c, comp_rows, comp_cols, gate)
            out_r.append(r)
            out_c.append(c)
    return np.concatenate(out_r), np.concatenate(out_c)


def _solve_buffered(comps, order, lab, r_idx, c_idx, cost, local_r, local_c, comp_rows,
                    comp_cols, gate):
    """The assigned (row node, column node) pairs of the components ``comps`` (all pairs inside
    the gate; ``order``: their pairs grouped by component in the order of ``comps``, ``lab``
    their components), from one flat buffer holding every component's augmented matrix as
    :func:`gated_assignment` builds it (n rows, m + n columns: the pairs' costs, big elsewhere,
    the rows' private miss columns at the gate), each solved by one ``linear_sum_assignment``."""
    n, m = comp_rows[comps], comp_cols[comps]
    width = m + n
    size = n * width
    # the buffer holds the components by shape (stable): one shape's are one (K, n, w) block
    shape = n * (int(width.max()) + 1) + width
    by_shape = np.argsort(shape, kind="stable")
    start = np.empty(len(comps), np.int64)
    start[by_shape] = np.r_[0, np.cumsum(size[by_shape])[:-1]]
    big = gate * (n + 1) + 1.0
    buf = np.repeat(big[by_shape], size[by_shape])
    new = np.empty(len(lab), bool)
    new[:1], new[1:] = True, lab[1:] != lab[:-1]
    k_of_pair = np.cumsum(new) - 1          # the pairs come grouped by component, in comps order
    lr, lc = local_r[r_idx[order]], local_c[c_idx[order]]
    buf[start[k_of_pair] + lr * width[k_of_pair] + lc] = cost[order]
    k_row = np.repeat(np.arange(len(comps)), n)
    row_base = np.r_[0, np.cumsum(n)[:-1]]
    row = np.arange(len(k_row)) - np.repeat(row_base, n)
    buf[start[k_row] + row * width[k_row] + m[k_row] + row] = gate
    col = _solve_by_shape(buf, start, n, width, shape, by_shape, row_base)
    # Back to nodes: the component's rows / columns in increasing index.
    node_r = np.empty(len(k_row), np.int64)
    node_r[row_base[k_of_pair] + lr] = r_idx[order]
    col_base = np.r_[0, np.cumsum(m)[:-1]]
    node_c = np.empty(int(m.sum()), np.int64)
    node_c[col_base[k_of_pair] + lc] = c_idx[order]
    real = col < m[k_row]
    ok = np.flatnonzero(real)
    ok = ok[buf[start[k_row[ok]] + row[ok] * width[k_row[ok]] + col[ok]]
            < big[k_row[ok]]]   # a gated pair, not a filler (never picked: costs more)
    return node_r[ok], node_c[col_base[k_row[ok]] + col[ok]]


#: Components of one shape are solved by iterating over their (K, n, w) block of the buffer
#: when there are at least this many of them (a view per matrix, ~0.3 us cheaper than slicing
#: and reshaping the flat buffer); the others one by one from the flat buffer.
_BLOCK_MIN = 8


def _solve_by_shape(buf, start, n, width, shape, by_shape, row_base):
    """``linear_sum_assignment``'s column of every row of the components whose matrices lie in
    ``buf`` (component k: ``n[k]`` rows of ``width[k]`` from ``start[k]``, laid out in the order
    ``by_shape``, which groups equal ``shape``), indexed as the rows of the components in their
    own order (component k's rows from ``row_base[k]``)."""
    col = np.empty(int(n.sum()), np.int64)
    sk = shape[by_shape]
    cuts = np.r_[0, np.flatnonzero(sk[1:] != sk[:-1]) + 1, len(sk)]
    count = np.diff(cuts)
    for g in np.flatnonzero(count >= _BLOCK_MIN).tolist():
        ks = by_shape[cuts[g]:cuts[g + 1]]
        a, w, s0 = int(n[ks[0]]), int(width[ks[0]]), int(start[ks[0]])
        block = buf[s0:s0 + len(ks) * a * w].reshape(len(ks), a, w)
        picked = [linear_sum_assignment(mat)[1] for mat in block]
        col[(row_base[ks][:, None] + np.arange(a)).ravel()] = np.concatenate(picked)
    small = np.flatnonzero(np.repeat(count < _BLOCK_MIN, count))
    if len(small):
        ks = by_shape[small]
        a, w, s0 = n[ks], width[ks], start[ks]
        picked = [linear_sum_assignment(buf[s:s + r * c].reshape(r, c))[1]
                  for s, r, c in zip(s0.tolist(), a.tolist(), w.tolist())]
        rows = np.arange(int(a.sum())) + np.repeat(row_base[ks] - np.r_[0, np.cumsum(a)[:-1]], a)
        col[rows] = np.concatenate(picked)
    return col


def _local_index(label: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Per node, its index among its component's nodes taken in increasing node index (as
    np.unique numbers them for :func:`gated_assignment`), filled for ``nodes`` only (every node
    of their components must be among them; other entries are undefined)."""
    involved = np.zeros(len(label), bool)
    involved[nodes] = True
    idx = np.flatnonzero(involved)
    o = small_key_order(label[idx], int(label[idx].max()) + 1 if len(idx) else 0)   # by component,
    # increasing index within
    lab = label[idx[o]]
    first = np.empty(len(lab), bool)
    first[:1] = True
    first[1:] = lab[1:] != lab[:-1]
    pos = np.arange(len(lab))
    out = np.empty(len(label), np.int64)
    out[idx[o]] = pos - np.maximum.accumulate(np.where(first, pos, 0))
    return out
