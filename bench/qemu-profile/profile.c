/* QEMU TCG plugin (plugin API v1, QEMU 7.2): instructions executed per translation block between
 * two marker addresses, for a per-function profile of a firmware run.
 *
 *   gcc -shared -fPIC -O2 -o libprofile.so profile.c
 *   qemu-system-arm ... -plugin ./libprofile.so,start=0xADDR,end=0xADDR,out=FILE
 *
 * Counting starts when the instruction at `start` executes and stops at `end` (pass the
 * addresses of a function's first instruction and of the instruction after its call); every
 * start..end region is accumulated. At exit FILE gets one line per translation block,
 * `vaddr insns executions`, and a line `total N`. bench/qemu-profile/symbolize.py turns that
 * into a table per function. The plugin API is declared here (Debian ships no header). */
#include <inttypes.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
typedef struct qemu_info_t qemu_info_t;
enum qemu_plugin_cb_flags { CB_NO_REGS, CB_R_REGS, CB_RW_REGS };
typedef void (*udata_cb_t)(qemu_plugin_id_t id, void *userdata);
typedef void (*vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
extern void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, tb_trans_cb_t cb);
extern void qemu_plugin_register_vcpu_tb_exec_cb(struct qemu_plugin_tb *tb, vcpu_udata_cb_t cb,
                                                 enum qemu_plugin_cb_flags flags, void *userdata);
extern void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, vcpu_udata_cb_t cb,
                                                   enum qemu_plugin_cb_flags flags, void *userdata);
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
extern uint64_t qemu_plugin_tb_vaddr(const struct qemu_plugin_tb *tb);
extern struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
extern uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
extern void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, udata_cb_t cb, void *userdata);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

/* One record per translated block (a block translated twice gets two records: both count). */
struct block {
    uint64_t vaddr;
    uint64_t insns;
    uint64_t execs;
    uint64_t partial; /* instructions of executions cut by a marker */
};
static struct block *blocks;
static size_t n_blocks, cap_blocks;
static uint64_t start_addr = UINT64_MAX, end_addr = UINT64_MAX;
static bool counting;
static struct block *current; /* the block being executed */
static char out_path[512] = "profile.txt";

/* Transitions between blocks (previous block index -> block index), counted while counting:
 * the symbolizer keeps those that enter a function at its first instruction (calls). */
#define EDGE_BITS 18
struct edge {
    uint32_t from, to;
    uint64_t n;
};
static struct edge edges[1 << EDGE_BITS];
static uint32_t previous = UINT32_MAX;

static void count_edge(uint32_t from, uint32_t to) {
    uint32_t h = (from * 2654435761u ^ to * 40503u) & ((1u << EDGE_BITS) - 1);
    for (;;) {
        struct edge *e = &edges[h];
        if (e->n == 0) {
            e->from = from;
            e->to = to;
        }
        if (e->from == from && e->to == to) {
            e->n++;
            return;
        }
        h = (h + 1) & ((1u << EDGE_BITS) - 1);
    }
}

static void on_tb(unsigned int vcpu, void *udata) {
    (void)vcpu;
    uint32_t k = (uint32_t)(uintptr_t)udata;
    current = &blocks[k];
    if (counting) {
        current->execs++;
        if (previous != UINT32_MAX) count_edge(previous, k);
    }
    previous = k;
}

/* udata = index within the block << 1 | is_end. A marker in the middle of a block: the block's
 * execution was counted whole (or not at all); correct by the instructions before the marker. */
static void on_marker(unsigned int vcpu, void *udata) {
    (void)vcpu;
    uintptr_t u = (uintptr_t)udata;
    uint64_t before = u >> 1;
    if (u & 1) {
        if (counting) {
            /* Counted whole: the instructions from the marker on were not in the region. */
            current->partial -= current->insns - before;
            counting = false;
        }
    } else if (!counting) {
        /* Not counted: the instructions from the marker on are. */
        current->partial += current->insns - before;
        counting = true;
    }
}

static void on_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb) {
    (void)id;
    if (n_blocks == cap_blocks) {
        cap_blocks = cap_blocks ? 2 * cap_blocks : 4096;
        blocks = realloc(blocks, cap_blocks * sizeof *blocks);
        if (!blocks) abort();
    }
    size_t k = n_blocks++;
    size_t n = qemu_plugin_tb_n_insns(tb);
    blocks[k] = (struct block){qemu_plugin_tb_vaddr(tb), n, 0, 0};
    qemu_plugin_register_vcpu_tb_exec_cb(tb, on_tb, CB_NO_REGS, (void *)(uintptr_t)k);
    for (size_t i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        uint64_t a = qemu_plugin_insn_vaddr(insn);
        if (a == start_addr || a == end_addr)
            qemu_plugin_register_vcpu_insn_exec_cb(insn, on_marker, CB_NO_REGS,
                                                   (void *)(uintptr_t)((i << 1) | (a == end_addr)));
    }
}

static void on_exit_cb(qemu_plugin_id_t id, void *p) {
    (void)id;
    (void)p;
    FILE *f = fopen(out_path, "w");
    if (!f) return;
    uint64_t total = 0;
    for (size_t k = 0; k < n_blocks; k++) {
        struct block *b = &blocks[k];
        uint64_t n = b->insns * b->execs + b->partial;
        if (n == 0) continue;
        total += n;
        fprintf(f, "%" PRIx64 " %" PRIu64 " %" PRIu64 "\n", b->vaddr, b->insns, n);
    }
    for (size_t h = 0; h < (1u << EDGE_BITS); h++)
        if (edges[h].n)
            fprintf(f, "edge %" PRIx64 " %" PRIx64 " %" PRIu64 "\n", blocks[edges[h].from].vaddr,
                    blocks[edges[h].to].vaddr, edges[h].n);
    fprintf(f, "total %" PRIu64 "\n", total);
    fclose(f);
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                                               int argc, char **argv) {
    (void)info;
    for (int i = 0; i < argc; i++) {
        if (!strncmp(argv[i], "start=", 6)) start_addr = strtoull(argv[i] + 6, NULL, 0) & ~1ULL;
        else if (!strncmp(argv[i], "end=", 4)) end_addr = strtoull(argv[i] + 4, NULL, 0) & ~1ULL;
        else if (!strncmp(argv[i], "out=", 4)) snprintf(out_path, sizeof out_path, "%s", argv[i] + 4);
    }
    if (start_addr == UINT64_MAX) counting = true;
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_trans);
    qemu_plugin_register_atexit_cb(id, on_exit_cb, NULL);
    return 0;
}
