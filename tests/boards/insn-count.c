/* A QEMU TCG plugin that counts the guest instructions a program executes (user-mode emulation):
 * tests/boards/count-instructions.sh builds it with the host's cc and loads it into Debian's
 * qemu-arm / qemu-aarch64 / qemu-x86_64 (package qemu-user), which support plugins but ship none.
 *
 *   qemu-arm -plugin libinsn-count.so -d plugin PROGRAM ...                 # the total
 *   qemu-arm -plugin libinsn-count.so,kinds=FILE -d plugin PROGRAM ...      # and by function
 *
 * With kinds=FILE every translated block is attributed to the function its first instruction
 * belongs to (the program's ELF symbols, as QEMU looks them up), and each function is of one of
 * three kinds: FILE has a line "r NAME" for each function of the rasterizer and "e NAME" for each
 * of the rest of the program (NAME as in the symbol table; count-instructions.sh sorts them by
 * the crate of the demangled name); any other function is shared code (the standard library,
 * the compiler's soft-float and division helpers, libc, other crates, code without a symbol).
 * Shared code counts for the function of the first two kinds that ran last on the same thread:
 * its caller or a caller's caller, so a rasterizer's 64-bit division or a pager's decompression
 * is the rasterizer's or the pager's. Before any such function runs (the C start-up) the
 * instructions count for the rest. At exit it prints one line per function, "symbol KIND OWNED
 * SELF NAME": KIND r, e or s (shared), OWNED the instructions counted for it (its own and those
 * of the shared code it called; 0 for shared code), SELF its own.
 *
 * Only the functions of QEMU's plugin API that it calls are declared here (API version 1,
 * QEMU 4.2 to 8.x; QEMU 9 replaced the inline counter by per-vCPU scoreboards).
 */
#include <inttypes.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
typedef struct qemu_info_t qemu_info_t;
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 };
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS };

extern void qemu_plugin_register_vcpu_tb_trans_cb(
    qemu_plugin_id_t id, void (*cb)(qemu_plugin_id_t, struct qemu_plugin_tb *));
extern size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
extern void qemu_plugin_register_vcpu_tb_exec_inline(struct qemu_plugin_tb *tb,
                                                     enum qemu_plugin_op op, void *ptr,
                                                     uint64_t imm);
extern void qemu_plugin_register_vcpu_tb_exec_cb(struct qemu_plugin_tb *tb,
                                                 void (*cb)(unsigned int vcpu, void *userdata),
                                                 enum qemu_plugin_cb_flags flags,
                                                 void *userdata);
extern struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb,
                                                        size_t idx);
extern const char *qemu_plugin_insn_symbol(const struct qemu_plugin_insn *insn);
extern void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id,
                                           void (*cb)(qemu_plugin_id_t, void *),
                                           void *userdata);
extern void qemu_plugin_outs(const char *string);

__attribute__((visibility("default"))) int qemu_plugin_version = 1;

static uint64_t instructions;

/* The kinds FILE names, by name: open addressing, FNV-1a of the name. */
#define KINDS (1 << 18)
static struct {
    char *name;
    char kind;
} kinds[KINDS];

static size_t hash(const char *name)
{
    uint64_t h = 0xcbf29ce484222325u;
    for (; *name; name++)
        h = (h ^ (unsigned char)*name) * 0x100000001b3u;
    return (size_t)(h % KINDS);
}

static char kind_of(const char *name)
{
    for (size_t h = hash(name); kinds[h].name; h = (h + 1) % KINDS)
        if (strcmp(kinds[h].name, name) == 0)
            return kinds[h].kind;
    return 's';
}

/* Reads FILE's "KIND NAME" lines; 0 if it cannot be read or has more names than fit. */
static int read_kinds(const char *path)
{
    char line[8192], *end;
    size_t n = 0;
    FILE *f = fopen(path, "r");
    if (f == NULL)
        return 0;
    while (fgets(line, sizeof line, f)) {
        if ((end = strchr(line, '\n')) != NULL)
            *end = 0;
        if (strlen(line) < 3)
            continue;
        if (++n > KINDS / 2) {
            fclose(f);
            return 0;
        }
        size_t h = hash(line + 2);
        while (kinds[h].name)
            h = (h + 1) % KINDS;
        kinds[h].name = strdup(line + 2);
        kinds[h].kind = line[0];
    }
    fclose(f);
    return 1;
}

/* By function: a fixed table, so that no block's callback ever sees it move. Names are QEMU's
 * own strings (its copy of the ELF symbol table), the same pointer for every block of a
 * function, so they are keyed by address. Slot 0 is the start-up code before any function of
 * the first two kinds, slot 1 code without a symbol. */
struct slot {
    const char *name;
    char kind;
    uint64_t owned, self;
};
#define SLOTS (1 << 16)
#define VCPUS 256
static struct slot slots[SLOTS] = {{"(start-up)", 'e', 0, 0}, {"(no symbol)", 's', 0, 0}};
static size_t used = 2;
static uint32_t table[2 * SLOTS]; /* open addressing, slot index + 1, 0 empty */
static size_t owner[VCPUS];        /* the last function of the first two kinds on each thread */
static int by_symbol;
static int table_full;

static size_t slot_of(const char *name)
{
    size_t h = ((uintptr_t)name >> 3) * 0x9e3779b1u % (2 * SLOTS);
    if (name == NULL)
        return 1;
    for (;; h = (h + 1) % (2 * SLOTS)) {
        if (table[h] == 0) {
            if (used == SLOTS) {
                table_full = 1;
                return 1;
            }
            slots[used].name = name;
            slots[used].kind = kind_of(name);
            table[h] = (uint32_t)++used;
            return used - 1;
        }
        if (slots[table[h] - 1].name == name)
            return table[h] - 1;
    }
}

/* A block ran: its instructions are its function's own, and count for that function or, in
 * shared code, for the thread's last stripmask function. */
static void executed(unsigned int vcpu, void *userdata)
{
    uintptr_t u = (uintptr_t)userdata;
    size_t s = u >> 16, *last = &owner[vcpu % VCPUS];
    uint64_t n = u & 0xffff;
    slots[s].self += n;
    if (slots[s].kind != 's')
        *last = s;
    slots[*last].owned += n;
}

/* Every translated block adds its instruction count each time it runs. */
static void translated(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    size_t n = qemu_plugin_tb_n_insns(tb);
    (void)id;
    qemu_plugin_register_vcpu_tb_exec_inline(tb, QEMU_PLUGIN_INLINE_ADD_U64, &instructions, n);
    if (by_symbol && n > 0) {
        size_t s = slot_of(qemu_plugin_insn_symbol(qemu_plugin_tb_get_insn(tb, 0)));
        qemu_plugin_register_vcpu_tb_exec_cb(tb, executed, QEMU_PLUGIN_CB_NO_REGS,
                                             (void *)(uintptr_t)(s << 16 | (n & 0xffff)));
    }
}

static void finished(qemu_plugin_id_t id, void *userdata)
{
    char line[4096];
    (void)id;
    (void)userdata;
    for (size_t s = 0; by_symbol && s < used; s++) {
        if (slots[s].owned == 0 && slots[s].self == 0)
            continue;
        snprintf(line, sizeof line, "symbol %c %" PRIu64 " %" PRIu64 " %s\n", slots[s].kind,
                 slots[s].owned, slots[s].self, slots[s].name);
        qemu_plugin_outs(line);
    }
    if (table_full)
        qemu_plugin_outs("insn-count: more than 65536 functions, the rest counted as without a symbol\n");
    snprintf(line, sizeof line, "guest instructions: %" PRIu64 "\n", instructions);
    qemu_plugin_outs(line);
}

__attribute__((visibility("default"))) int qemu_plugin_install(qemu_plugin_id_t id,
                                                                const qemu_info_t *info,
                                                                int argc, char **argv)
{
    (void)info;
    for (int i = 0; i < argc; i++) {
        if (strncmp(argv[i], "kinds=", 6) != 0)
            continue;
        if (!read_kinds(argv[i] + 6)) {
            fprintf(stderr, "insn-count: cannot read %s (or it names too many functions)\n",
                    argv[i] + 6);
            return -1;
        }
        by_symbol = 1;
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, translated);
    qemu_plugin_register_atexit_cb(id, finished, NULL);
    return 0;
}
