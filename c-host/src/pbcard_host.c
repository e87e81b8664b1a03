/* pbcard_host.c: the C reference host of the pbcard DPM interface over SPI (issue 16 item 5).
 * See pbcard_host.h; the frames are docs/SPI.md, the image docs/DPM.md. Portable C99, no
 * malloc, no global state. */
#include "pbcard_host.h"

#include <string.h>

/* Capabilities the CYCLIC exchange needs. */
#define NEEDED_CAPS (PBCARD_CAP_CARD_EVENTS | PBCARD_CAP_DRIVE_REPORTS | PBCARD_CAP_DRIVE_CMD | PBCARD_CAP_DRIVE_STATE)
/* The open sequence: header, STATUS, then the counters of the blocks the host writes. */
enum { OPEN_HEADER, OPEN_STATUS, OPEN_DRIVE, OPEN_CONFIG, OPEN_MBX_RSP, OPEN_STATE, OPEN_DONE };

static uint16_t get16(const uint8_t *b) { return (uint16_t)((b[0] << 8) | b[1]); }

static void put16(uint8_t *b, uint16_t v)
{
    b[0] = (uint8_t)(v >> 8);
    b[1] = (uint8_t)v;
}

static uint16_t next_seq(uint16_t s) { return s == 0xFFFFu ? 1u : (uint16_t)(s + 1u); }

uint16_t pbc_crc16(const uint8_t *data, size_t len)
{
    uint16_t crc = PBCARD_SPI_CRC_INIT;
    size_t i;
    int bit;
    for (i = 0; i < len; i++) {
        crc ^= (uint16_t)(data[i] << 8);
        for (bit = 0; bit < 8; bit++) {
            crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ PBCARD_SPI_CRC_POLY) : (uint16_t)(crc << 1);
        }
    }
    return crc;
}

void pbc_init(pbc_host *h, const pbc_options *o)
{
    memset(h, 0, sizeof *h);
    h->o = *o;
    if (h->o.card_timeout_ms == 0) {
        h->o.card_timeout_ms = 200;
    }
    if (h->o.sck_hz == 0) {
        h->o.sck_hz = 1000000u;
    }
    if (h->o.cyclic_bytes == 0) {
        h->o.cyclic_bytes = PBCARD_CYC_TRANSACTION_BYTES;
    }
    h->cyc_reply_len = PBCARD_CYC_MAX_REPLY_DATA - PBCARD_CYC_MAX_FRAGMENT;
    h->cmd_len = PBCARD_DRIVE_CMD_SEQ_TAIL - PBCARD_DRIVE_CMD_FLAGS;
    h->mbx_hint = -1;
}

void pbc_set_fault(pbc_host *h, uint16_t code)
{
    if (code != 0 && code != h->fault_code) {
        h->fault_count++;
    }
    h->drive_dirty |= code != h->fault_code;
    h->fault_code = code;
}

void pbc_set_warning(pbc_host *h, uint16_t code)
{
    if (code != 0 && code != h->warning_code) {
        h->warning_count++;
    }
    h->drive_dirty |= code != h->warning_code;
    h->warning_code = code;
}

void pbc_set_irq_mask(pbc_host *h, uint16_t mask)
{
    h->drive_dirty |= mask != h->irq_mask;
    h->irq_mask = mask;
}

void pbc_set_config(pbc_host *h, const pbc_config *c)
{
    h->config = *c;
    h->have_config = 1;
    h->config_dirty = 1;
    h->config_state = PBC_CONFIG_WRITING;
}

int pbc_config_outcome(const pbc_host *h) { return h->have_config ? h->config_state : PBC_CONFIG_NONE; }

uint16_t pbc_open_request(const pbc_host *h) { return h->request_open; }

uint16_t pbc_boot_id(const pbc_host *h) { return h->boot_id; }

int pbc_is_open(const pbc_host *h) { return h->open; }

const pbc_stats *pbc_get_stats(const pbc_host *h) { return &h->stats; }

int pbc_respond(pbc_host *h, uint16_t id, const pbc_param_response *rsp)
{
    uint8_t *b = h->rsp_blk;
    uint8_t n = rsp->values_len > PBCARD_MBX_CAPACITY ? PBCARD_MBX_CAPACITY : rsp->values_len;
    uint16_t seq;
    if (id == 0 || h->request_open != id) {
        return PBC_E_STALE;
    }
    if (h->rsp_active) {
        return PBC_E_BUSY;
    }
    /* MBX_RSP encoded whole; pbc_cycle sends it in fragments: the body (head, fields,
     * values), then the tail once the body is confirmed. */
    seq = next_seq(h->seq_rsp);
    h->seq_rsp = seq;
    memset(b, 0, PBCARD_MBX_RSP_SIZE);
    put16(&b[PBCARD_MBX_RSP_SEQ_HEAD], seq);
    put16(&b[PBCARD_MBX_RSP_REQ_ID], id);
    b[PBCARD_MBX_RSP_RESULT] = rsp->result ? 1u : 0u;
    h->rsp_len = PBCARD_MBX_RSP_VALUES;
    if (rsp->result == 0) {
        b[PBCARD_MBX_RSP_FORMAT] = rsp->format;
        b[PBCARD_MBX_RSP_COUNT] = rsp->count;
        b[PBCARD_MBX_RSP_VALUES_LEN] = n;
        memcpy(&b[PBCARD_MBX_RSP_VALUES], rsp->values, n);
        h->rsp_len += n;
    } else {
        put16(&b[PBCARD_MBX_RSP_ERROR], rsp->error);
        put16(&b[PBCARD_MBX_RSP_ERROR_INFO], rsp->error_info);
        b[PBCARD_MBX_RSP_HAS_INFO] = rsp->has_info ? 1u : 0u;
    }
    put16(&b[PBCARD_MBX_RSP_SEQ_TAIL], seq);
    h->rsp_confirmed = 0;
    h->rsp_next = 0;
    h->rsp_active = 1;
    h->request_open = 0;
    return PBC_OK;
}

/* ---------------------------------------------------------------------------------------
 * Transactions and the budget */

/* Microseconds a transaction of n bytes costs: its clocks, and the gap before it (none
 * before the first of a call: the caller's cycle provides it). */
static uint32_t cost_us(const pbc_host *h, size_t n, int first)
{
    uint64_t bits = (uint64_t)n * 8u * 1000000u;
    uint32_t us = (uint32_t)((bits + h->o.sck_hz - 1u) / h->o.sck_hz);
    return us + (first ? 0u : PBCARD_SPI_T_READY_US);
}

static int fits(const pbc_host *h, uint32_t us)
{
    if (us > h->left_us) {
        return 0;
    }
    return 1;
}

static int transfer(pbc_host *h, size_t n)
{
    uint32_t us = cost_us(h, n, h->first_tx);
    if (!h->first_tx && h->o.wait != NULL) {
        h->o.wait(h->o.user, PBCARD_SPI_T_READY_US);
    }
    h->first_tx = 0;
    h->left_us = us > h->left_us ? 0u : h->left_us - us;
    if (h->out != NULL) {
        h->out->transactions++;
        h->out->bytes += (uint32_t)n;
        h->out->used_us += us;
    }
    return h->o.transfer(h->o.user, h->mosi, h->miso, n) == 0 ? PBC_OK : PBC_E_NO_REPLY;
}

/* Encode a request into mosi, zero-padded to total bytes; returns the frame length. */
static size_t encode(pbc_host *h, uint8_t cmd, uint16_t addr, uint16_t len, const uint8_t *data, size_t dlen,
                     size_t total, uint8_t *tag)
{
    size_t n = PBCARD_SPI_REQUEST_HEADER + dlen + PBCARD_SPI_CRC_LEN;
    *tag = h->tag++;
    h->mosi[0] = cmd;
    h->mosi[1] = *tag;
    put16(&h->mosi[2], addr);
    put16(&h->mosi[4], len);
    if (dlen > 0) {
        memcpy(&h->mosi[PBCARD_SPI_REQUEST_HEADER], data, dlen);
    }
    put16(&h->mosi[n - PBCARD_SPI_CRC_LEN], pbc_crc16(h->mosi, n - PBCARD_SPI_CRC_LEN));
    if (total > n) {
        memset(&h->mosi[n], 0, total - n);
    }
    return n;
}

typedef struct {
    uint8_t result, tag, cmd, flags;
    uint16_t addr;
    const uint8_t *data;
    size_t len;
} reply;

/* Decode the MISO of the last transaction (n bytes): 0 = a well-formed reply. */
static int decode(const pbc_host *h, size_t n, reply *r)
{
    size_t k;
    if (n < PBCARD_SPI_REPLY_HEADER + PBCARD_SPI_CRC_LEN || h->miso[0] < PBCARD_SPI_RESULT_OK
        || h->miso[0] > PBCARD_SPI_RESULT_FORBIDDEN_WRITE) {
        return -1;
    }
    k = get16(&h->miso[6]);
    if (PBCARD_SPI_REPLY_HEADER + k + PBCARD_SPI_CRC_LEN > n) {
        return -1;
    }
    if (pbc_crc16(h->miso, PBCARD_SPI_REPLY_HEADER + k) != get16(&h->miso[PBCARD_SPI_REPLY_HEADER + k])) {
        return -1;
    }
    r->result = h->miso[0];
    r->tag = h->miso[1];
    r->cmd = h->miso[2];
    r->flags = h->miso[3];
    r->addr = get16(&h->miso[4]);
    r->data = &h->miso[PBCARD_SPI_REPLY_HEADER];
    r->len = k;
    return 0;
}

/* One READ / WRITE / STATUS access: the request, then a STATUS request padded to the reply,
 * whose MISO is the reply. Both transactions must fit the budget, or nothing is sent. No
 * retry here: the caller's job stays queued for the next cycle. On PBC_OK, *data points at
 * the reply's DATA (want bytes) in miso. */
static int access(pbc_host *h, uint8_t cmd, uint16_t addr, uint16_t len, const uint8_t *wdata, size_t want,
                  const uint8_t **data)
{
    size_t dlen = cmd == PBCARD_SPI_CMD_WRITE ? len : 0u;
    size_t frame = PBCARD_SPI_REQUEST_HEADER + dlen + PBCARD_SPI_CRC_LEN;
    size_t fetch = PBCARD_SPI_REPLY_HEADER + want + PBCARD_SPI_CRC_LEN;
    uint8_t tag, tag2;
    uint16_t crc;
    reply r;
    if (fetch < PBCARD_SPI_REQUEST_HEADER + PBCARD_SPI_CRC_LEN) {
        fetch = PBCARD_SPI_REQUEST_HEADER + PBCARD_SPI_CRC_LEN;
    }
    if (!fits(h, cost_us(h, frame, h->first_tx) + cost_us(h, fetch, 0))) {
        h->stats.budget_short++;
        return PBC_E_BUDGET;
    }
    encode(h, cmd, addr, len, wdata, dlen, frame, &tag);
    crc = get16(&h->mosi[frame - PBCARD_SPI_CRC_LEN]);
    h->cyc_pending = 0;
    if (transfer(h, frame) != PBC_OK) {
        return PBC_E_NO_REPLY;
    }
    encode(h, PBCARD_SPI_CMD_STATUS, 0, 0, NULL, 0, fetch, &tag2);
    if (transfer(h, fetch) != PBC_OK || decode(h, fetch, &r) != 0) {
        return PBC_E_NO_REPLY;
    }
    if (r.tag != tag || r.cmd != cmd || r.addr != addr || r.result != PBCARD_SPI_RESULT_OK || r.len != want) {
        return PBC_E_NO_REPLY;
    }
    if (cmd == PBCARD_SPI_CMD_WRITE && get16(r.data) != crc) {
        return PBC_E_NO_REPLY;
    }
    *data = r.data;
    return PBC_OK;
}

static int read_image(pbc_host *h, uint16_t addr, uint16_t len, const uint8_t **data)
{
    return access(h, PBCARD_SPI_CMD_READ, addr, len, NULL, len, data);
}

static int write_image(pbc_host *h, uint16_t addr, const uint8_t *wdata, uint16_t len)
{
    const uint8_t *d;
    return access(h, PBCARD_SPI_CMD_WRITE, addr, len, wdata, PBCARD_SPI_WRITE_ECHO_LEN, &d);
}

/* ---------------------------------------------------------------------------------------
 * Open */

static int open_step(pbc_host *h)
{
    const uint8_t *d;
    int r;
    switch (h->open_step) {
    case OPEN_HEADER: {
        uint16_t version, size;
        uint32_t caps;
        r = read_image(h, PBCARD_HEADER_START, PBCARD_HEADER_SIZE, &d);
        if (r != PBC_OK) {
            return r;
        }
        version = get16(&d[PBCARD_HEADER_LAYOUT_VERSION]);
        size = get16(&d[PBCARD_HEADER_IMAGE_SIZE]);
        caps = ((uint32_t)get16(&d[PBCARD_HEADER_CAPABILITIES]) << 16) | get16(&d[PBCARD_HEADER_CAPABILITIES + 2]);
        if (memcmp(&d[PBCARD_HEADER_MAGIC], PBCARD_DPM_MAGIC, 4) != 0 || version < 3 || size < PBCARD_DPM_IMAGE_SIZE_V3
            || (caps & NEEDED_CAPS) != NEEDED_CAPS) {
            /* Not (yet) a card this host can drive: try again from the header. */
            h->bad_card = 1;
            return PBC_E_BAD_CARD;
        }
        h->caps = (uint16_t)caps;
        break;
    }
    case OPEN_STATUS:
        r = access(h, PBCARD_SPI_CMD_STATUS, 0, 0, NULL, PBCARD_SPI_STATUS_LEN, &d);
        if (r != PBC_OK) {
            return r;
        }
        if (d[PBCARD_SPI_STATUS_VERSION] < PBCARD_SPI_PROTOCOL_VERSION) {
            h->bad_card = 1;
            h->open_step = OPEN_HEADER;
            return PBC_E_BAD_CARD;
        }
        break;
    case OPEN_DRIVE:
        r = read_image(h, PBCARD_DRIVE_START, 4, &d);
        if (r != PBC_OK) {
            return r;
        }
        h->seq_drive = get16(&d[PBCARD_DRIVE_SEQ_HEAD]);
        h->heartbeat = get16(&d[PBCARD_DRIVE_HEARTBEAT]);
        break;
    case OPEN_CONFIG:
        r = read_image(h, PBCARD_CONFIG_START, 2, &d);
        if (r != PBC_OK) {
            return r;
        }
        h->seq_config = get16(d);
        break;
    case OPEN_MBX_RSP:
        r = read_image(h, PBCARD_MBX_RSP_START, 4, &d);
        if (r != PBC_OK) {
            return r;
        }
        h->seq_rsp = get16(&d[PBCARD_MBX_RSP_SEQ_HEAD]);
        h->request_seen = get16(&d[PBCARD_MBX_RSP_REQ_ID]);
        break;
    case OPEN_STATE:
        r = read_image(h, PBCARD_DRIVE_STATE_START, 2, &d);
        if (r != PBC_OK) {
            return r;
        }
        h->seq_state = get16(d);
        break;
    default:
        break;
    }
    h->bad_card = 0;
    h->open_step++;
    if (h->open_step == OPEN_DONE) {
        h->open = 1;
        h->stats.opens++;
        h->request_open = 0;
        h->rsp_active = 0;
        h->req_active = 0;
        h->mbx_hint = -1;
        h->cyc_pending = 0;
        h->drive_dirty = 1; /* the report and the IRQ mask, once */
    }
    return PBC_OK;
}

/* ---------------------------------------------------------------------------------------
 * The CYCLIC exchange */

static size_t state_bytes(const pbc_drive_state *s, uint8_t *p)
{
    size_t words = s->extra_count > PBCARD_EXTRA_WORDS ? PBCARD_EXTRA_WORDS : s->extra_count;
    size_t i, n;
    const size_t base = PBCARD_DRIVE_STATE_FLAGS;
    put16(&p[PBCARD_DRIVE_STATE_FLAGS - base], s->flags);
    put16(&p[PBCARD_DRIVE_STATE_SPEED - base], (uint16_t)s->speed);
    put16(&p[PBCARD_DRIVE_STATE_CURRENT - base], (uint16_t)s->current);
    put16(&p[PBCARD_DRIVE_STATE_TORQUE - base], (uint16_t)s->torque);
    put16(&p[PBCARD_DRIVE_STATE_POWER - base], (uint16_t)s->power);
    put16(&p[PBCARD_DRIVE_STATE_FAULT_CODE - base], s->fault_code);
    put16(&p[PBCARD_DRIVE_STATE_WARNING_CODE - base], s->warning_code);
    put16(&p[PBCARD_DRIVE_STATE_NAMUR - base], s->namur);
    if (words == 0 && s->inputs_seq == 0) {
        return PBCARD_CYC_STATE_BASE;
    }
    put16(&p[PBCARD_DRIVE_STATE_INPUTS_SEQ - base], s->inputs_seq);
    p[PBCARD_DRIVE_STATE_EXTRA_COUNT - base] = (uint8_t)words;
    p[PBCARD_DRIVE_STATE_EXTRA_COUNT - base + 1] = 0;
    for (i = 0; i < words; i++) {
        put16(&p[PBCARD_DRIVE_STATE_EXTRA - base + 2 * i], s->extra[i]);
    }
    n = PBCARD_DRIVE_STATE_EXTRA - base + 2 * words;
    return n;
}

/* The MISO of the last transaction (n bytes) as the reply to the CYCLIC request tagged tag:
 * 0 = taken into out. */
static int take_cyclic(pbc_host *h, size_t n, uint8_t tag, pbc_cycle_result *out, const uint8_t **frag,
                       size_t *frag_len)
{
    reply r;
    size_t c, q, i;
    const uint8_t *d;
    if (decode(h, n, &r) != 0 || r.tag != tag || r.cmd != PBCARD_SPI_CMD_CYCLIC || r.addr != 0
        || r.result != PBCARD_SPI_RESULT_OK || r.len < PBCARD_CYC_REPLY_FIXED) {
        return -1;
    }
    d = r.data;
    c = d[PBCARD_CYC_REP_CMD_LEN];
    q = d[PBCARD_CYC_REP_REQ_LEN];
    if (r.len != PBCARD_CYC_REPLY_FIXED + c + q || c > PBCARD_DRIVE_CMD_SEQ_TAIL - PBCARD_DRIVE_CMD_FLAGS
        || (c > 0 && c < PBCARD_CYC_CMD_BASE)) {
        return -1;
    }
    h->cyc_reply_len = r.len - q;
    h->cmd_len = c;
    *frag = &d[PBCARD_CYC_REPLY_FIXED + c];
    *frag_len = q;
    out->pending_events = get16(&d[PBCARD_CYC_REP_EVENTS]);
    out->card_flags = d[PBCARD_CYC_REP_CARD_FLAGS];
    out->comm_state = d[PBCARD_CYC_REP_COMM_STATE];
    h->card_heartbeat_new = get16(&d[PBCARD_CYC_REP_CARD_HEARTBEAT]);
    h->boot_id_new = get16(&d[PBCARD_CYC_REP_BOOT_ID]);
    memcpy(h->events_new, &d[PBCARD_CYC_REP_CARD_EVENTS], PBCARD_CARD_EVENT_COUNT);
    memset(&out->command, 0, sizeof out->command);
    out->have_command = 0;
    if (get16(&d[PBCARD_CYC_REP_CMD_SEQ]) != 0 && c >= PBCARD_CYC_CMD_BASE) {
        const uint8_t *b = &d[PBCARD_CYC_REP_CMD];
        const size_t base = PBCARD_DRIVE_CMD_FLAGS;
        pbc_drive_cmd *m = &out->command;
        size_t words;
        m->seq = get16(&d[PBCARD_CYC_REP_CMD_SEQ]);
        m->flags = get16(&b[PBCARD_DRIVE_CMD_FLAGS - base]);
        m->speed_setpoint = (int16_t)get16(&b[PBCARD_DRIVE_CMD_SPEED_SETPOINT - base]);
        m->fault_resets = b[PBCARD_DRIVE_CMD_FAULT_RESETS - base];
        m->comm_loss_reaction = b[PBCARD_DRIVE_CMD_COMM_LOSS_REACTION - base];
        m->operate_mode = b[PBCARD_DRIVE_CMD_OPERATE_MODE - base];
        m->telegram = get16(&b[PBCARD_DRIVE_CMD_TELEGRAM - base]);
        m->outputs_seq = get16(&b[PBCARD_DRIVE_CMD_OUTPUTS_SEQ - base]);
        words = (c - PBCARD_CYC_CMD_BASE) / 2;
        m->extra_count = (uint8_t)words;
        for (i = 0; i < words; i++) {
            m->extra[i] = get16(&b[PBCARD_DRIVE_CMD_EXTRA - base + 2 * i]);
        }
        out->have_command = 1;
    }
    return 0;
}

/* ---------------------------------------------------------------------------------------
 * The mailbox through the CYCLIC fragments (docs/SPI.md "One drive cycle") */

/* What the telegram leaves of the transaction budget after used bytes (a fragment's size). */
static size_t room(const pbc_host *h, size_t used)
{
    size_t r = h->o.cyclic_bytes > used ? h->o.cyclic_bytes - used : 0u;
    if (r < PBCARD_CYC_MIN_FRAGMENT) {
        r = PBCARD_CYC_MIN_FRAGMENT;
    }
    return r > PBCARD_CYC_MAX_FRAGMENT ? PBCARD_CYC_MAX_FRAGMENT : r;
}

/* Bytes of the request being assembled from offset 0 through its values, as far as known. */
static size_t req_need(const pbc_host *h)
{
    size_t v;
    if (h->req_have <= PBCARD_MBX_REQ_VALUES_LEN) {
        return PBCARD_MBX_REQ_VALUES;
    }
    v = h->req_blk[PBCARD_MBX_REQ_VALUES_LEN];
    return PBCARD_MBX_REQ_VALUES + (v > PBCARD_MBX_CAPACITY ? PBCARD_MBX_CAPACITY : v);
}

/* MBX_REQ assembled: a new request goes to the parameter callback. */
static void take_request(pbc_host *h)
{
    const uint8_t *d = h->req_blk;
    pbc_param_request q;
    uint16_t id = get16(&d[PBCARD_MBX_REQ_REQ_ID]);
    if (get16(&d[PBCARD_MBX_REQ_SEQ_HEAD]) == 0 || id == 0 || id == h->request_seen) {
        return;
    }
    memset(&q, 0, sizeof q);
    q.id = id;
    q.kind = d[PBCARD_MBX_REQ_KIND];
    q.axis = d[PBCARD_MBX_REQ_AXIS];
    q.pnu = get16(&d[PBCARD_MBX_REQ_PNU]);
    q.subindex = get16(&d[PBCARD_MBX_REQ_SUBINDEX]);
    q.count = d[PBCARD_MBX_REQ_COUNT];
    q.format = d[PBCARD_MBX_REQ_FORMAT];
    q.values_len = d[PBCARD_MBX_REQ_VALUES_LEN] > PBCARD_MBX_CAPACITY ? PBCARD_MBX_CAPACITY
                                                                       : d[PBCARD_MBX_REQ_VALUES_LEN];
    memcpy(q.values, &d[PBCARD_MBX_REQ_VALUES], q.values_len);
    h->request_seen = id;
    h->request_open = id;
    h->rsp_active = 0; /* an answer to an older request is no longer wanted */
    h->stats.requests++;
    if (h->o.param != NULL) {
        pbc_param_response a;
        memset(&a, 0, sizeof a);
        if (h->o.param(h->o.param_user, &q, &a)) {
            (void)pbc_respond(h, id, &a);
        }
    }
}

/* A reply's MBX_REQ fragment f (flen bytes) for the asked (off, len); changed: the reply's
 * events say MBX_REQ changed since the host read its head. Offset 0 starts a request, the
 * next fragments extend it; a one-fragment request is whole (a consistent copy), a longer
 * one once the 2-byte fragment at SEQ_TAIL equals its head (the counter only grows). */
static void req_fragment(pbc_host *h, size_t off, size_t len, const uint8_t *f, size_t flen, int changed)
{
    if (len == 0 || flen != len) {
        if (changed && h->req_active && h->req_have > 0) {
            h->req_active = 0;
        }
        return;
    }
    if (off == 0) {
        memcpy(h->req_blk, f, len);
        h->req_have = len;
        h->req_frags = 1;
        h->req_active = 1;
    } else if (changed) {
        h->req_active = 0; /* the head read with offset 0 is no longer the block's */
        return;
    } else if (h->req_active) {
        if (off == PBCARD_MBX_REQ_SEQ_TAIL && len == 2 && h->req_have >= req_need(h)) {
            if (get16(f) != get16(h->req_blk)) {
                h->req_active = 0; /* fragments of two requests: again from offset 0 */
                h->mbx_hint = -1;
                return;
            }
            h->req_frags = 1;
        } else if (off == h->req_have && off + len <= PBCARD_MBX_REQ_SEQ_TAIL) {
            memcpy(&h->req_blk[off], f, len);
            h->req_have += len;
            h->req_frags++;
        }
    }
    if (!h->req_active || h->req_have < req_need(h) || h->req_frags != 1) {
        return;
    }
    h->req_active = 0;
    take_request(h);
}

/* The reply to a request that carried the MBX_RSP fragment (off, len) came back OK: it is
 * applied; the confirmed tail completes the answer. */
static void rsp_confirmed(pbc_host *h, size_t off, size_t len)
{
    if (!h->rsp_active || len == 0) {
        return;
    }
    if (off == PBCARD_MBX_RSP_SEQ_TAIL && h->rsp_confirmed >= h->rsp_len) {
        h->rsp_active = 0;
        h->stats.responses++;
    } else if (off <= h->rsp_confirmed && off + len <= h->rsp_len && off + len > h->rsp_confirmed) {
        h->rsp_confirmed = off + len;
    }
}

/* One CYCLIC exchange: one transaction when the last one was a CYCLIC request (its MISO
 * is the reply to it), else two (the same request again fetches the reply to the first).
 * The mailbox fragments each way are sized to what the telegram leaves of the budget. */
static int cyclic(pbc_host *h, const pbc_drive_state *state, pbc_cycle_result *out)
{
    uint8_t data[PBCARD_CYC_MAX_REQUEST_DATA];
    size_t s, k, frame, n, n2, req_room, rsp_room, ask_off = 0, ask_len = 0, rsp_off = 0, rsp_n = 0;
    size_t flen = 0, a_req_off, a_req_len, a_rsp_off, a_rsp_len;
    const uint8_t *frag = NULL;
    uint8_t tag1, tag2;
    int steady = h->cyc_pending, ok = 0, previous = 0, changed;
    memset(data, 0, sizeof data);
    s = state_bytes(state, &data[PBCARD_CYC_REQ_STATE]);
    rsp_room = room(h, PBCARD_SPI_REQUEST_HEADER + PBCARD_CYC_REQUEST_FIXED + s + PBCARD_SPI_CRC_LEN);
    req_room = room(h, PBCARD_SPI_REPLY_HEADER + PBCARD_CYC_REPLY_FIXED + h->cmd_len + PBCARD_SPI_CRC_LEN);
    if (h->req_active) {
        size_t need = req_need(h);
        if (h->req_have < need) {
            ask_off = h->req_have;
            ask_len = need - h->req_have < req_room ? need - h->req_have : req_room;
        } else {
            ask_off = PBCARD_MBX_REQ_SEQ_TAIL;
            ask_len = 2;
        }
    } else if ((h->caps & PBCARD_CAP_MAILBOX) && h->mbx_hint != 0) {
        ask_len = req_room; /* MBX_REQ changed (or unknown): its first fragment */
    }
    if (h->rsp_active) {
        if (h->rsp_confirmed >= h->rsp_len) {
            rsp_off = PBCARD_MBX_RSP_SEQ_TAIL;
            rsp_n = 2;
        } else {
            rsp_off = h->rsp_next >= h->rsp_len ? h->rsp_confirmed : h->rsp_next;
            rsp_n = h->rsp_len - rsp_off < rsp_room ? h->rsp_len - rsp_off : rsp_room;
        }
        memcpy(&data[PBCARD_CYC_REQUEST_FIXED + s], &h->rsp_blk[rsp_off], rsp_n);
    }
    k = PBCARD_CYC_REQUEST_FIXED + s + rsp_n;
    frame = PBCARD_SPI_REQUEST_HEADER + k + PBCARD_SPI_CRC_LEN;
    /* Clocked as long as the reply expected: the last one's length without its fragment,
     * plus the fragment the answered request asked. */
    n = PBCARD_SPI_REPLY_HEADER + h->cyc_reply_len + h->car_req_len + PBCARD_SPI_CRC_LEN;
    n = n > frame ? n : frame;
    /* The fetch of a two-transaction cycle: for the longest command (the first attempt may
     * have failed because the command grew: a new telegram), plus the fragment asked. */
    n2 = PBCARD_SPI_REPLY_HEADER + PBCARD_CYC_MAX_REPLY_DATA - PBCARD_CYC_MAX_FRAGMENT + ask_len + PBCARD_SPI_CRC_LEN;
    n2 = n2 > frame ? n2 : frame;
    if (!fits(h, cost_us(h, steady ? n : frame, h->first_tx) + (steady ? 0u : cost_us(h, n2, 0)))) {
        h->stats.budget_short++;
        return PBC_E_BUDGET;
    }
    if (h->rsp_active && rsp_off != PBCARD_MBX_RSP_SEQ_TAIL) {
        h->rsp_next = rsp_off + rsp_n;
    }
    /* The counters advance even if the exchange fails (the card may have applied it). */
    h->heartbeat = next_seq(h->heartbeat);
    h->seq_drive = next_seq(h->seq_drive);
    h->seq_state = next_seq(h->seq_state);
    put16(&data[PBCARD_CYC_REQ_HEARTBEAT], h->heartbeat);
    put16(&data[PBCARD_CYC_REQ_DRIVE_SEQ], h->seq_drive);
    put16(&data[PBCARD_CYC_REQ_STATE_SEQ], h->seq_state);
    data[PBCARD_CYC_REQ_STATE_LEN] = (uint8_t)s;
    data[PBCARD_CYC_REQ_RSP_OFF] = (uint8_t)rsp_off;
    data[PBCARD_CYC_REQ_RSP_LEN] = (uint8_t)rsp_n;
    data[PBCARD_CYC_REQ_REQ_OFF] = (uint8_t)ask_off;
    data[PBCARD_CYC_REQ_REQ_LEN] = (uint8_t)ask_len;
    /* What the request answered by the reply carried: the last one (one transaction) or
     * this one (two). */
    a_req_off = h->car_req_off;
    a_req_len = h->car_req_len;
    a_rsp_off = h->car_rsp_off;
    a_rsp_len = h->car_rsp_len;
    h->car_req_off = (uint8_t)ask_off;
    h->car_req_len = (uint8_t)ask_len;
    h->car_rsp_off = (uint8_t)rsp_off;
    h->car_rsp_len = (uint8_t)rsp_n;
    if (steady) {
        encode(h, PBCARD_SPI_CMD_CYCLIC, 0, (uint16_t)k, data, k, n, &tag1);
        if (transfer(h, n) == PBC_OK && take_cyclic(h, n, h->cyc_tag, out, &frag, &flen) == 0) {
            h->cyc_tag = tag1;
            ok = 1;
            previous = 1;
        }
    } else {
        encode(h, PBCARD_SPI_CMD_CYCLIC, 0, (uint16_t)k, data, k, frame, &tag1);
        if (transfer(h, frame) != PBC_OK) {
            h->cyc_pending = 0;
            h->rsp_next = h->rsp_confirmed;
            h->mbx_hint = -1;
            return PBC_E_NO_REPLY;
        }
    }
    if (!ok) {
        h->cyc_pending = 1;
        h->cyc_tag = tag1;
        if (!fits(h, cost_us(h, n2, 0))) {
            h->stats.budget_short++;
            h->rsp_next = h->rsp_confirmed;
            return PBC_E_BUDGET;
        }
        /* The same request once more: its MISO is the reply to the first (the card applies
         * it again with the same counters: no change). */
        encode(h, PBCARD_SPI_CMD_CYCLIC, 0, (uint16_t)k, data, k, n2, &tag2);
        if (transfer(h, n2) != PBC_OK) {
            h->cyc_pending = 0;
        } else {
            h->cyc_tag = tag2;
            ok = take_cyclic(h, n2, tag1, out, &frag, &flen) == 0;
        }
    }
    if (!ok) {
        /* A reply longer than expected (the telegram changed) was cut: clock the longest. */
        h->cyc_reply_len = PBCARD_CYC_MAX_REPLY_DATA - PBCARD_CYC_MAX_FRAGMENT;
        h->rsp_next = h->rsp_confirmed; /* whatever is not confirmed goes again */
        h->mbx_hint = -1;
        return PBC_E_NO_REPLY;
    }
    if (!previous) {
        a_req_off = ask_off;
        a_req_len = ask_len;
        a_rsp_off = rsp_off;
        a_rsp_len = rsp_n;
    }
    changed = (out->pending_events & (1u << PBCARD_MBX_REQ_EVENT_BIT)) != 0;
    h->mbx_hint = changed;
    rsp_confirmed(h, a_rsp_off, a_rsp_len);
    req_fragment(h, a_req_off, a_req_len, frag, flen, changed);
    return PBC_OK;
}

/* ---------------------------------------------------------------------------------------
 * Queued accesses: CONFIG, the mailbox, the CONFIG acknowledge */

static int write_config(pbc_host *h)
{
    uint8_t b[PBCARD_CONFIG_SIZE];
    uint16_t seq = next_seq(h->seq_config);
    int r;
    memset(b, 0, sizeof b);
    put16(&b[PBCARD_CONFIG_SEQ_HEAD], seq);
    b[PBCARD_CONFIG_STATION_ADDRESS] = h->config.station_address;
    b[PBCARD_CONFIG_PROFILE] = h->config.profile;
    b[PBCARD_CONFIG_OPERATE_MODE] = h->config.operate_mode;
    b[PBCARD_CONFIG_COMM_LOSS_REACTION] = h->config.comm_loss_reaction;
    put16(&b[PBCARD_CONFIG_TELEGRAM], h->config.telegram);
    put16(&b[PBCARD_CONFIG_IO_UPDATE_DELAY], h->config.io_update_delay);
    put16(&b[PBCARD_CONFIG_SEQ_TAIL], seq);
    if (!fits(h, cost_us(h, PBCARD_SPI_REQUEST_HEADER + sizeof b + PBCARD_SPI_CRC_LEN, h->first_tx))) {
        h->stats.budget_short++;
        return PBC_E_BUDGET;
    }
    /* Advanced even if the write fails: a half-written block is never completed under the
     * same number. */
    h->seq_config = seq;
    r = write_image(h, PBCARD_CONFIG_START, b, (uint16_t)sizeof b);
    if (r == PBC_OK) {
        h->config_dirty = 0;
        h->config_seq = seq;
        h->config_state = PBC_CONFIG_WRITING;
    }
    return r;
}

static int read_config_ack(pbc_host *h)
{
    const uint8_t *d;
    int r = read_image(h, PBCARD_CARD_START, PBCARD_CARD_SIZE, &d);
    if (r != PBC_OK) {
        return r;
    }
    if (get16(&d[PBCARD_CARD_SEQ_HEAD]) == 0 || get16(&d[PBCARD_CARD_SEQ_HEAD]) != get16(&d[PBCARD_CARD_SEQ_TAIL])
        || get16(&d[PBCARD_CARD_CONFIG_ACK]) != h->config_seq) {
        return PBC_OK;
    }
    switch (d[PBCARD_CARD_CONFIG_RESULT]) {
    case 1: h->config_state = PBC_CONFIG_ACCEPTED; break;
    case 2: h->config_state = PBC_CONFIG_PENDING; break;
    case 3: h->config_state = PBC_CONFIG_REFUSED; break;
    case 4: h->config_state = PBC_CONFIG_ADDRESS_LOCKED; break;
    default: break;
    }
    return PBC_OK;
}

/* DRIVE whole (a changed fault / warning report, the IRQ mask) under the next counter; the
 * CYCLIC exchange keeps it, writing only the heartbeat. */
static int write_drive(pbc_host *h)
{
    uint8_t b[PBCARD_DRIVE_SIZE];
    uint16_t seq = next_seq(h->seq_drive);
    int r;
    memset(b, 0, sizeof b);
    put16(&b[PBCARD_DRIVE_SEQ_HEAD], seq);
    put16(&b[PBCARD_DRIVE_HEARTBEAT], h->heartbeat);
    put16(&b[PBCARD_DRIVE_FAULT_CODE], h->fault_code);
    put16(&b[PBCARD_DRIVE_WARNING_CODE], h->warning_code);
    b[PBCARD_DRIVE_FAULT_COUNT] = h->fault_count;
    b[PBCARD_DRIVE_WARNING_COUNT] = h->warning_count;
    put16(&b[PBCARD_DRIVE_IRQ_MASK], h->irq_mask);
    put16(&b[PBCARD_DRIVE_SEQ_TAIL], seq);
    if (!fits(h, cost_us(h, PBCARD_SPI_REQUEST_HEADER + sizeof b + PBCARD_SPI_CRC_LEN, h->first_tx))) {
        h->stats.budget_short++;
        return PBC_E_BUDGET;
    }
    h->seq_drive = seq;
    r = write_image(h, PBCARD_DRIVE_START, b, (uint16_t)sizeof b);
    if (r == PBC_OK) {
        h->drive_dirty = 0;
        h->stats.drive_writes++;
    }
    return r;
}

/* ---------------------------------------------------------------------------------------
 * The drive cycle */

static void observe_card(pbc_host *h, uint32_t now_ms, int seen, pbc_cycle_result *out)
{
    size_t i;
    if (seen) {
        if (h->boot_id_new != 0 && h->boot_id != 0 && h->boot_id_new != h->boot_id) {
            /* The card restarted: open again, rewrite CONFIG, resynchronise the event
             * counters, forget the mailbox (its request ids start again). */
            out->card_restarted = 1;
            h->stats.card_restarts++;
            h->open = 0;
            h->open_step = OPEN_HEADER;
            h->events_valid = 0;
            h->config_dirty = h->have_config;
            if (h->have_config) {
                h->config_state = PBC_CONFIG_WRITING;
            }
            h->request_open = 0;
            h->rsp_active = 0;
            h->req_active = 0;
            h->mbx_hint = -1;
        }
        h->boot_id = h->boot_id_new;
        if (h->events_valid) {
            for (i = 0; i < PBCARD_CARD_EVENT_COUNT; i++) {
                out->card_events[i] = (uint8_t)(h->events_new[i] - h->events_seen[i]);
            }
        }
        memcpy(h->events_seen, h->events_new, PBCARD_CARD_EVENT_COUNT);
        h->events_valid = 1;
        if (!h->card_seen || h->card_heartbeat_new != h->card_heartbeat) {
            h->card_heartbeat = h->card_heartbeat_new;
            h->card_changed_ms = now_ms;
            h->card_seen = 1;
        }
    }
    out->card_alive = h->card_seen && (uint32_t)(now_ms - h->card_changed_ms) <= h->o.card_timeout_ms;
    if (!out->card_alive && h->card_seen && !h->card_lost) {
        h->card_lost = 1;
        out->card_lost = 1;
        h->stats.card_losses++;
    }
    if (out->card_alive) {
        h->card_lost = 0;
    }
}

int pbc_cycle(pbc_host *h, uint32_t now_ms, uint32_t budget_us, const pbc_drive_state *state,
              pbc_cycle_result *out)
{
    int r = PBC_OK, jobs;
    if (h == NULL || state == NULL || out == NULL) {
        return PBC_E_ARG;
    }
    memset(out, 0, sizeof *out);
    h->out = out;
    h->left_us = budget_us;
    h->first_tx = 1;
    while (!h->open) {
        r = open_step(h);
        if (r != PBC_OK) {
            observe_card(h, now_ms, 0, out);
            h->out = NULL;
            return r == PBC_E_BAD_CARD ? PBC_E_BAD_CARD : PBC_OPENING;
        }
    }
    r = cyclic(h, state, out);
    if (r == PBC_OK) {
        h->stats.cycles_ok++;
    } else if (r == PBC_E_NO_REPLY) {
        h->stats.no_reply++;
    }
    observe_card(h, now_ms, r == PBC_OK, out);
    /* With what is left of the budget: the queued accesses, most urgent first. */
    for (jobs = 0; jobs < 4 && h->open; jobs++) {
        int j;
        if (h->config_dirty) {
            j = write_config(h);
        } else if (h->drive_dirty) {
            j = write_drive(h);
        } else if (h->have_config && h->config_state == PBC_CONFIG_WRITING) {
            j = read_config_ack(h);
            if (j == PBC_OK && h->config_state == PBC_CONFIG_WRITING) {
                break; /* once per cycle */
            }
        } else {
            break;
        }
        if (j != PBC_OK) {
            break;
        }
    }
    h->out = NULL;
    return r;
}
