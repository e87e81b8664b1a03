/* drive.c: a minimal drive on top of the C reference host, for the end-to-end test
 * (host-tests/tests/c_host.rs links it with pbcard_host.c and connects the SPI transfer to
 * the card's in-process SPI slave). A drive maker's control board looks the same: one
 * pbc_cycle per drive cycle, the command applied, the status sent, parameters served. */
#include "pbcard_host.h"

#include <string.h>

/* DRIVE_CMD.FLAGS / DRIVE_STATE.FLAGS bits used here (docs/DPM.md). */
#define CMD_RUN 0x0001u
#define ST_READY 0x0001u
#define ST_RUNNING 0x0002u
#define ST_AT_REFERENCE 0x0020u
#define ST_ZERO_SPEED 0x0040u
#define ST_FLUX_READY 0x0080u
#define ST_FIELDBUS_CONTROL 0x0100u
#define ST_FAULT 0x0008u
#define ST_WARNING 0x0010u
#define CMD_COAST 0x0004u
/* PROFIdrive parameter format Word (0x42) and error "impermissible parameter number". */
#define FORMAT_WORD 0x42u
#define ERR_PNU 0x00u

static pbc_host host;
static pbc_drive_state state;
static pbc_cycle_result last;
static uint16_t cmd_flags;
static int16_t cmd_setpoint;
static int32_t speed;
static uint16_t pnus[2] = {100u, 101u};
static uint16_t values[2] = {50u, 60u};
static uint32_t restarts, max_used_us, max_transactions, commands;
static int last_result;
static uint16_t fault, warning;
static uint32_t max_bytes_steady, mailbox_cycles;

static int serve(void *user, const pbc_param_request *q, pbc_param_response *a)
{
    size_t i;
    (void)user;
    for (i = 0; i < 2; i++) {
        if (q->pnu != pnus[i]) {
            continue;
        }
        if (q->kind == 2) {
            if (q->values_len != 2) {
                a->result = 1;
                a->error = 0x17u; /* format */
                return 1;
            }
            values[i] = (uint16_t)((q->values[0] << 8) | q->values[1]);
            a->result = 0;
            return 1;
        }
        a->result = 0;
        a->format = FORMAT_WORD;
        a->count = 1;
        a->values_len = 2;
        a->values[0] = (uint8_t)(values[i] >> 8);
        a->values[1] = (uint8_t)values[i];
        return 1;
    }
    a->result = 1;
    a->error = ERR_PNU;
    return 1;
}

int pbch_drive_init(pbc_transfer_fn transfer, void *user, uint32_t sck_hz, uint16_t telegram)
{
    pbc_options o;
    pbc_config c;
    memset(&o, 0, sizeof o);
    o.transfer = transfer;
    o.user = user;
    o.sck_hz = sck_hz;
    o.card_timeout_ms = 200;
    o.param = serve;
    pbc_init(&host, &o);
    memset(&c, 0, sizeof c);
    c.station_address = 126; /* keep the card's */
    c.telegram = telegram;
    pbc_set_config(&host, &c);
    memset(&state, 0, sizeof state);
    speed = 0;
    cmd_flags = 0;
    cmd_setpoint = 0;
    restarts = 0;
    max_used_us = 0;
    max_transactions = 0;
    commands = 0;
    fault = 0;
    warning = 0;
    max_bytes_steady = 0;
    mailbox_cycles = 0;
    return 0;
}

/* The drive trips with fault code (0 = the fault cleared): DRIVE.FAULT_CODE (the card's
 * Ext_Diag and diagnostic alarm) and DRIVE_STATE's fault bit and code (ZSW1, PNU 947). */
void pbch_set_fault(uint16_t code)
{
    fault = code;
    pbc_set_fault(&host, code);
}

/* A warning (0 = none): DRIVE.WARNING_CODE and DRIVE_STATE's warning bit and code. */
void pbch_set_warning(uint16_t code)
{
    warning = code;
    pbc_set_warning(&host, code);
}

/* One drive cycle of 1 ms: exchange, then the drive model (a ramp of 0x100 per ms). */
int pbch_drive_step(uint32_t now_ms, uint32_t budget_us)
{
    int32_t target;
    last_result = pbc_cycle(&host, now_ms, budget_us, &state, &last);
    if (last.card_restarted) {
        restarts++;
    }
    if (last.used_us > max_used_us) {
        max_used_us = last.used_us;
    }
    if (last.transactions > max_transactions) {
        max_transactions = last.transactions;
    }
    if (last.transactions == 1 && last.bytes > max_bytes_steady) {
        max_bytes_steady = last.bytes;
    }
    if (last.have_command) {
        cmd_flags = last.command.flags;
        cmd_setpoint = last.command.speed_setpoint;
        commands++;
    }
    target = (cmd_flags & CMD_RUN) && fault == 0 ? cmd_setpoint : 0;
    if (speed < target) {
        speed = speed + 0x100 > target ? target : speed + 0x100;
    } else if (speed > target) {
        speed = speed - 0x100 < target ? target : speed - 0x100;
    }
    state.flags = ST_READY | ST_FIELDBUS_CONTROL;
    if (cmd_flags & CMD_RUN) {
        state.flags |= ST_RUNNING | ST_FLUX_READY;
        if (speed == target) {
            state.flags |= ST_AT_REFERENCE;
        }
    }
    if (speed == 0) {
        state.flags |= ST_ZERO_SPEED;
    }
    if (fault != 0) {
        state.flags = (uint16_t)((state.flags & ~(ST_RUNNING | ST_AT_REFERENCE)) | ST_FAULT);
    }
    if (warning != 0) {
        state.flags |= ST_WARNING;
    }
    state.fault_code = fault;
    state.warning_code = warning;
    state.speed = (int16_t)speed;
    state.current = (int16_t)(speed / 4);
    return last_result;
}

/* What the test looks at. */
uint16_t pbch_cmd_flags(void) { return cmd_flags; }
int16_t pbch_cmd_setpoint(void) { return cmd_setpoint; }
int16_t pbch_speed(void) { return (int16_t)speed; }
uint32_t pbch_restarts(void) { return restarts; }
uint32_t pbch_commands(void) { return commands; }
uint32_t pbch_requests(void) { return pbc_get_stats(&host)->requests; }
uint32_t pbch_responses(void) { return pbc_get_stats(&host)->responses; }
uint32_t pbch_opens(void) { return pbc_get_stats(&host)->opens; }
uint32_t pbch_cycles_ok(void) { return pbc_get_stats(&host)->cycles_ok; }
uint32_t pbch_budget_short(void) { return pbc_get_stats(&host)->budget_short; }
uint32_t pbch_max_used_us(void) { return max_used_us; }
uint32_t pbch_max_transactions(void) { return max_transactions; }
uint32_t pbch_max_bytes_steady(void) { return max_bytes_steady; }
uint32_t pbch_drive_writes(void) { return pbc_get_stats(&host)->drive_writes; }
uint32_t pbch_last_transactions(void) { return last.transactions; }
uint32_t pbch_last_bytes(void) { return last.bytes; }
uint32_t pbch_last_used_us(void) { return last.used_us; }
int pbch_card_alive(void) { return last.card_alive; }
uint8_t pbch_comm_state(void) { return last.comm_state; }
int pbch_config_outcome(void) { return pbc_config_outcome(&host); }
uint16_t pbch_boot_id(void) { return pbc_boot_id(&host); }
int pbch_is_open(void) { return pbc_is_open(&host); }
uint16_t pbch_value(uint32_t i) { return i < 2 ? values[i] : 0; }
uint16_t pbch_crc16(const uint8_t *p, uint32_t n) { return pbc_crc16(p, n); }
uint8_t pbch_card_event(uint32_t i) { return i < PBCARD_CARD_EVENT_COUNT ? last.card_events[i] : 0; }
