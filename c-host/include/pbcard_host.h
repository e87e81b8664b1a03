/* pbcard_host.h: the C reference host of the pbcard DPM interface over SPI (issue 16 item 5).
 *
 * What a drive's control board (the SPI master) runs against the PROFIBUS card: open and
 * version check, one CYCLIC exchange per drive cycle (heartbeat, drive-neutral status out;
 * card heartbeat, events, boot id, drive-neutral command in), the parameter mailbox
 * served to a callback through the CYCLIC exchange's fragments (no block access), the drive's
 * fault / warning reports (DRIVE), CONFIG written and rewritten after a card restart
 * (CARD.BOOT_ID).
 *
 * Portable C99, no malloc, no global state: the caller owns a pbc_host and hands in an SPI
 * transfer callback, the time and, per call, a time budget. pbc_cycle never starts a
 * transaction that would take it past the budget (SPI clock and the inter-transaction gap
 * SPI_T_READY_US are counted); work that does not fit is resumed in the next call.
 * The frames and the image are docs/SPI.md and docs/DPM.md; every number comes from the
 * generated pbcard_dpm.h. */
#ifndef PBCARD_HOST_H
#define PBCARD_HOST_H

#include <stddef.h>
#include <stdint.h>

#include "pbcard_dpm.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One full-duplex SPI transaction: NSS low, len bytes out of mosi while len bytes come into
 * miso, NSS high. Returns 0 on success. */
typedef int (*pbc_transfer_fn)(void *user, const uint8_t *mosi, uint8_t *miso, size_t len);
/* Wait at least us microseconds (the gap between two transactions); may be NULL when the
 * transfer function itself leaves SPI_T_READY_US after NSS rises. */
typedef void (*pbc_wait_fn)(void *user, uint32_t us);

/* The drive-neutral status the drive sends every cycle (DRIVE_STATE, docs/DPM.md). */
typedef struct {
    uint16_t flags; /* bit 0 ready, 1 running, 2 reverse, 3 fault, 4 warning, ... */
    int16_t speed;  /* N2, 0x4000 = 100 % */
    int16_t current;
    int16_t torque;
    int16_t power;
    uint16_t fault_code;
    uint16_t warning_code;
    uint16_t namur;
    uint16_t inputs_seq; /* 0: no INPUTS block written with this state */
    uint8_t extra_count; /* valid words of extra */
    uint16_t extra[PBCARD_EXTRA_WORDS];
} pbc_drive_state;

/* The drive-neutral command the card sends (DRIVE_CMD). */
typedef struct {
    uint16_t seq; /* DRIVE_CMD.SEQ_HEAD */
    uint16_t flags; /* bit 0 run, 1 reverse, 2 coast, 3 quick stop, ... 12 communication lost */
    int16_t speed_setpoint;
    uint8_t fault_resets;
    uint8_t comm_loss_reaction;
    uint8_t operate_mode;
    uint8_t extra_count;
    uint16_t telegram;
    uint16_t outputs_seq;
    uint16_t extra[PBCARD_EXTRA_WORDS];
} pbc_drive_cmd;

/* CONFIG (host -> card). */
typedef struct {
    uint8_t station_address; /* 126 = keep the card's */
    uint8_t profile;
    uint8_t operate_mode;
    uint8_t comm_loss_reaction;
    uint16_t telegram; /* 0 = any module */
    uint16_t io_update_delay;
} pbc_config;

/* A parameter request from MBX_REQ. */
typedef struct {
    uint16_t id;
    uint8_t kind; /* 1 read value, 2 write value, 3 read description */
    uint8_t axis;
    uint16_t pnu;
    uint16_t subindex;
    uint8_t count;
    uint8_t format;
    uint8_t values_len;
    uint8_t values[PBCARD_MBX_CAPACITY];
} pbc_param_request;

/* The answer written to MBX_RSP. */
typedef struct {
    uint8_t result; /* 0 values / done, 1 error */
    uint8_t format;
    uint8_t count;
    uint8_t values_len;
    uint16_t error;
    uint16_t error_info;
    uint8_t has_info;
    uint8_t values[PBCARD_MBX_CAPACITY];
} pbc_param_response;

/* A new parameter request: fill rsp and return 1 (answered now), or return 0 and answer later
 * with pbc_respond (within the card's mailbox timeout, 500 ms). */
typedef int (*pbc_param_fn)(void *user, const pbc_param_request *req, pbc_param_response *rsp);

typedef struct {
    pbc_transfer_fn transfer;
    pbc_wait_fn wait; /* may be NULL */
    void *user;
    uint32_t sck_hz; /* the SPI clock, for the budget (e.g. 10000000) */
    uint32_t card_timeout_ms; /* CARD.HEARTBEAT unchanged this long = card lost (A140); 0 = 200 */
    pbc_param_fn param; /* may be NULL: requests stay unanswered (the card answers 0x11) */
    void *param_user;
    uint32_t cyclic_bytes; /* bytes one CYCLIC transaction may clock; 0 = PBCARD_CYC_TRANSACTION_BYTES (64).
                            * The mailbox fragments get what the telegram leaves of it, each way
                            * (PBCARD_CYC_MIN_FRAGMENT..PBCARD_CYC_MAX_FRAGMENT bytes). */
} pbc_options;

/* Results of pbc_cycle and the other calls. */
enum {
    PBC_OK = 0,
    PBC_OPENING = 1, /* not open yet (header, version, counters being read): call again */
    PBC_E_BUDGET = -1, /* the budget did not allow the exchange this cycle */
    PBC_E_NO_REPLY = -2, /* no valid reply this cycle (transport, a late card): next cycle tries */
    PBC_E_BAD_CARD = -3, /* magic, layout version, image size, capabilities or protocol too old */
    PBC_E_BUSY = -4, /* pbc_respond: an answer is still being written */
    PBC_E_STALE = -5, /* pbc_respond: not the open request */
    PBC_E_ARG = -6
};

/* Where the CONFIG written last stands (CARD.CONFIG_ACK / CONFIG_RESULT). */
enum {
    PBC_CONFIG_NONE = 0, /* none set */
    PBC_CONFIG_WRITING = 1, /* to be written / written, no acknowledge yet */
    PBC_CONFIG_ACCEPTED = 2,
    PBC_CONFIG_PENDING = 3, /* valid; the card waits until no cyclic exchange runs */
    PBC_CONFIG_REFUSED = 4,
    PBC_CONFIG_ADDRESS_LOCKED = 5
};

typedef struct {
    int have_command; /* command holds a consistent DRIVE_CMD from this cycle */
    pbc_drive_cmd command;
    uint8_t comm_state; /* STATUS.COMM_STATE, P0740 coding */
    uint8_t card_flags; /* CARD.FLAGS */
    uint16_t pending_events; /* the pending-events bitmap */
    uint8_t card_events[PBCARD_CARD_EVENT_COUNT]; /* new card events since the last cycle */
    int card_alive; /* CARD.HEARTBEAT changed within the timeout */
    int card_lost; /* became lost in this cycle */
    int card_restarted; /* CARD.BOOT_ID changed: re-opening, CONFIG rewritten, counters resynced */
    uint32_t transactions; /* SPI transactions in this call */
    uint32_t bytes; /* bytes clocked in this call */
    uint32_t used_us; /* budget used (clock time of the bytes + the gaps) */
} pbc_cycle_result;

/* Counters (wrapping). */
typedef struct {
    uint32_t cycles_ok;
    uint32_t no_reply;
    uint32_t budget_short; /* exchanges or jobs put off for the budget */
    uint32_t requests; /* parameter requests taken */
    uint32_t responses; /* answers written (the tail fragment confirmed) */
    uint32_t drive_writes; /* DRIVE written whole (a changed fault / warning report) */
    uint32_t card_restarts;
    uint32_t card_losses;
    uint32_t opens;
} pbc_stats;

/* The host state; treat as opaque. */
typedef struct {
    pbc_options o;
    uint8_t mosi[PBCARD_SPI_MAX_TRANSACTION];
    uint8_t miso[PBCARD_SPI_MAX_TRANSACTION];
    uint8_t tag;
    int cyc_pending; /* the last transaction was a CYCLIC request, tagged cyc_tag */
    uint8_t cyc_tag;
    size_t cyc_reply_len;
    int open; /* 0 closed, 1 open */
    int open_step;
    int bad_card;
    uint16_t caps;
    uint16_t seq_drive, seq_state, seq_config, seq_rsp;
    uint16_t heartbeat;
    uint16_t boot_id;
    uint16_t card_heartbeat;
    uint16_t card_heartbeat_new, boot_id_new; /* from the reply just taken */
    uint8_t events_new[PBCARD_CARD_EVENT_COUNT];
    uint32_t card_changed_ms;
    int card_seen, card_lost;
    int events_valid;
    uint8_t events_seen[PBCARD_CARD_EVENT_COUNT];
    int have_config, config_dirty, config_state;
    pbc_config config;
    uint16_t config_seq;
    /* The mailbox through the CYCLIC fragments (docs/SPI.md "One drive cycle"). */
    int mbx_hint; /* from the last reply: MBX_REQ changed (1), unchanged (0), unknown (-1) */
    uint16_t request_seen; /* REQ_ID taken last */
    uint16_t request_open; /* REQ_ID taken, not answered (0 = none) */
    uint8_t req_blk[PBCARD_MBX_REQ_SIZE]; /* MBX_REQ being assembled from reply fragments */
    size_t req_have; /* bytes req_blk[0..req_have) received */
    int req_frags; /* fragments they came in (1 = one consistent copy; else the tail decides) */
    int req_active;
    uint8_t rsp_blk[PBCARD_MBX_RSP_SIZE]; /* MBX_RSP being sent in request fragments */
    size_t rsp_len, rsp_confirmed, rsp_next; /* body bytes, confirmed below, next to send */
    int rsp_active;
    uint8_t car_req_off, car_req_len, car_rsp_off, car_rsp_len; /* what the last request carried */
    size_t cmd_len; /* DRIVE_CMD bytes of the last reply */
    /* The drive's report (DRIVE), written whole when it changes. */
    uint16_t fault_code, warning_code, irq_mask;
    uint8_t fault_count, warning_count;
    int drive_dirty;
    uint32_t left_us; /* of this call's budget */
    int first_tx; /* no transaction yet in this call (no gap before it) */
    pbc_cycle_result *out;
    pbc_stats stats;
} pbc_host;

/* CRC-16/CCITT-FALSE (the frame CRC). */
uint16_t pbc_crc16(const uint8_t *data, size_t len);

/* Set up (nothing is sent; pbc_cycle opens the interface). */
void pbc_init(pbc_host *h, const pbc_options *o);

/* Set the CONFIG; written by the next calls of pbc_cycle, and again after a card restart. */
void pbc_set_config(pbc_host *h, const pbc_config *c);

/* Where the CONFIG stands (PBC_CONFIG_*). */
int pbc_config_outcome(const pbc_host *h);

/* One drive cycle: at most budget_us of SPI time (transactions and their gaps). While not
 * open, it opens (PBC_OPENING); then one CYCLIC exchange (one transaction, two at most),
 * and with what is left of the budget one queued access (CONFIG, the mailbox). */
int pbc_cycle(pbc_host *h, uint32_t now_ms, uint32_t budget_us, const pbc_drive_state *state,
              pbc_cycle_result *out);

/* Report the drive's active fault (0 = none) in DRIVE.FAULT_CODE; a new non-zero code counts
 * a new fault (DRIVE.FAULT_COUNT). The card raises Ext_Diag and a diagnostic alarm for a fault.
 * Written whole by the next pbc_cycle (one queued access), then kept by the CYCLIC exchange.
 * The drive's DRIVE_STATE fault_code / warning_code (pbc_drive_state) feed the profile (ZSW1,
 * the fault buffer PNU 947); a drive sets both, as the Rust host's set_fault does. */
void pbc_set_fault(pbc_host *h, uint16_t code);

/* Report the active warning (0 = none) in DRIVE.WARNING_CODE, like pbc_set_fault. */
void pbc_set_warning(pbc_host *h, uint16_t code);

/* DRIVE.IRQ_MASK: bits of the pending-events bitmap that do not assert IRQ (docs/SPI.md). */
void pbc_set_irq_mask(pbc_host *h, uint16_t mask);

/* Answer request id later (pbc_param_fn returned 0); sent by the next pbc_cycle calls in
 * MBX_RSP fragments. */
int pbc_respond(pbc_host *h, uint16_t id, const pbc_param_response *rsp);

/* The open request (0 = none). */
uint16_t pbc_open_request(const pbc_host *h);

/* CARD.BOOT_ID as last seen (0 = not yet). */
uint16_t pbc_boot_id(const pbc_host *h);

/* Whether the interface is open. */
int pbc_is_open(const pbc_host *h);

/* The counters. */
const pbc_stats *pbc_get_stats(const pbc_host *h);

#ifdef __cplusplus
}
#endif

#endif /* PBCARD_HOST_H */
