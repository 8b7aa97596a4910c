/* The client core's content bounds (ms_core_opening.content_lo / _hi): the box
 * of the model's geometry, from the root's complex at root precision. The
 * root is the first cell decoded and drawn of every model and its complex is
 * the image of the whole model on the grid of 2^root_bits cells a side, so the
 * box of the grid cells its vertices stand for holds every vertex of the model
 * and is within one root quantum (box_side / 2^root_bits) of their box on
 * every side (ms_view_cell_bounds). The index's records say much less: with
 * an index by subtree only the head's cells are known at open, whose cubes
 * can be a quarter of the model's cube loose on a side, or the whole cube for
 * a model of one cell.
 *
 * Until the bounds are known the root's bytes are wanted up to root
 * precision (a few kilobytes, which the memory budget lets through as it does
 * the index's subtrees: a far model's root would otherwise wait behind the
 * near models' cells, and its viewer with it). The bounds are read from the
 * root as soon as the selection shows it at root precision or finer (on most
 * views it takes the root there itself while the view streams in); a root the
 * selection keeps coarser is decoded there for the bounds and back once the
 * view is complete, so the view, its memory and its frames are the
 * selection's and a streaming view does not decode its root twice. Before the caller's
 * first camera the decode thread serves a camera of its own that needs
 * nothing more (and no APO), so ms_core_wait_open can hand the bounds over
 * with the index, before anything is drawn. */
#include "ms_client_core_internal.h"

/* The precision the bounds are taken at: root_bits (a one-cell model's root
 * is a leaf, whose window goes on to p), or a coarser preview's last bit. */
static unsigned content_bits(const ms_core *c)
{
    const ms_archive_cell *root = ms_archive_get_cell(c->index, 0);
    unsigned root_bits = ms_archive_get_header(c->index)->root_bits;
    unsigned bits = root->bits_max < root_bits ? root->bits_max : root_bits;
    /* a preview coarser than root precision: its bounds, a little looser */
    if (c->dec.preview_steps && c->dec.preview_steps - 1u < bits)
        bits = c->dec.preview_steps - 1u;
    return bits;
}

bool ms_core_content_camera(const ms_core *c, ms_camera *camera)
{
    if (c->content != CONTENT_PENDING || !ms_archive_get_cell(c->index, 0))
        return false;
    /* one pixel looking at the model's cube from outside: every cell needs a
     * few bits at most, so the root's floor is all it asks for */
    const ms_archive_header *h = ms_archive_get_header(c->index);
    double centre[3], eye[3], up[3] = {0, 1, 0};
    for (int a = 0; a < 3; ++a)
        centre[a] = eye[a] = h->box_origin[a] + 0.5 * h->box_side;
    eye[2] += 2.0 * h->box_side;
    ms_error err;
    return ms_camera_look_at(eye, centre, up, 60.0, 1.0, 1.0, 0.01 * h->box_side,
                             10.0 * h->box_side, camera, &err) == MS_OK;
}

unsigned ms_core_content_goal(const ms_core *c, uint32_t cell, unsigned goal)
{
    if (c->content != CONTENT_PENDING || cell != 0)
        return goal;
    unsigned bits = content_bits(c);
    return goal > bits ? goal : bits;
}

bool ms_core_content_want(const ms_core *c, const want *w)
{
    return c->content == CONTENT_PENDING && w->cell == 0 && w->stream == STREAM_GEOMETRY;
}

/* The root's bounds at root precision, decoded there when it is shown
 * coarser, and back (ms_view_set_bits is exactly reversible: the view, its
 * memory and its frames stay as the selection left them) unless `stay`: a
 * pass of the content camera, which makes no frame, leaves it there for the
 * caller's first selection, which usually wants it there or finer (and
 * otherwise coarsens it before its first frame). */
static ms_status root_bounds(ms_core *c, unsigned bits, bool stay, double lo[3], double hi[3], ms_error *err)
{
    unsigned shown = ms_view_bits(c->dec.view, 0);
    if (shown >= bits)
        return ms_view_cell_bounds(c->dec.view, 0, lo, hi, err);
    ms_status st = ms_view_set_bits(c->dec.view, 0, bits, err);
    if (st == MS_OK)
        st = ms_view_cell_bounds(c->dec.view, 0, lo, hi, err);
    ms_error back_err;
    if (!stay && ms_view_set_bits(c->dec.view, 0, shown, &back_err) != MS_OK && st == MS_OK) {
        *err = back_err;
        st = back_err.code;
    }
    return st;
}

void ms_core_content_note(ms_core *c, bool now, bool for_content)
{
    const ms_archive_cell *root = ms_archive_get_cell(c->index, 0);
    if (c->content != CONTENT_PENDING || !root || ms_view_state(c->dec.view, 0) == MS_VIEW_HIDDEN)
        return;
    int content = CONTENT_PENDING;
    double lo[3], hi[3];
    unsigned bits = content_bits(c);
    if (root->geometry_length == 0) {
        content = CONTENT_NONE; /* an empty model */
    } else if (ms_view_bits(c->dec.view, 0) >= bits || (now && ms_view_available_bits(c->dec.view, 0) >= bits)) {
        ms_error err;
        ms_status st = root_bounds(c, bits, for_content, lo, hi, &err);
        content = st == MS_OK ? CONTENT_KNOWN : CONTENT_NONE;
        if (st != MS_OK && st != MS_ERR_EMPTY)
            ms_core_warn(c, err.text);
    } else if (ms_core_dcell(c, 0)->failed) {
        content = CONTENT_NONE; /* left below root precision for good */
    }
    if (content == CONTENT_PENDING)
        return;
    pthread_mutex_lock(&c->lock);
    c->content = content;
    if (content == CONTENT_KNOWN)
        for (int a = 0; a < 3; ++a)
            c->content_lo[a] = lo[a], c->content_hi[a] = hi[a];
    pthread_mutex_unlock(&c->lock);
}
