/* rmw_cosim_gate: cosim's lockstep gate at the ROS 2 middleware (RMW) layer.
 *
 * An RMW implementation that forwards every rmw_* function to a real one (librmw_fastrtps_cpp,
 * what the pip wheels ship, opened with dlopen at the first call) and
 * gates the subscriptions cosim feeds, so that any program on rcl (C, rclcpp, rclpy) takes each
 * tick's inputs as one whole. The forwarding of the functions this file does not define is
 * generated at build time (tools/build_native.py: one jump per function the real library
 * exports); the gated ones are here: rmw_create_subscription / rmw_destroy_subscription,
 * rmw_subscription_event_init, rmw_wait, the rmw_take* of subscriptions, rmw_create_publisher /
 * rmw_destroy_publisher and the rmw_publish* (counted on outputs), rmw_destroy_node and
 * rmw_get_implementation_identifier ("rmw_cosim_gate", what RMW_IMPLEMENTATION names).
 *
 * The protocol is the Python gate's (runtime/foreign_gate/cosim_gate.py), with the same feeder
 * (orchestrator/proxies/foreign_proxy.py): the program's inputs and /clock are remapped below
 * a private prefix (/cosim/feed/<node>/); for every tick j it is due at, the feeder publishes
 * one message on each input due at j, then the Clock of j, and it feeds the next tick only once
 * the gate acknowledged j on <prefix>taken (std_msgs/Int64MultiArray, reliable, transient
 * local, depth 1000): [j, n_1, ..., n_m], n_i the messages the program published on output i
 * (the configured outputs, in their order: sorted graph topics) since the previous
 * acknowledgement, counted in rmw_publish, rmw_publish_serialized_message and
 * rmw_publish_loaned_message of the publishers it created on that topic. The gate
 * acknowledges [-1] ("ready") once each gated subscription matched a publisher.
 *
 * Configuration: COSIM_RMW_GATE, one item a line (tools: orchestrator/proxies/foreign_launch.py):
 *   prefix /cosim/feed/ctl/
 *   node ctl
 *   period 5                      (ticks between the program's activations)
 *   start 0
 *   input odom 5 0 0              (topic below prefix, period, phase, first tick with a sample)
 *   output /cmd_vel               (a resolved output topic; the acknowledgement's order)
 * Without it the library only forwards.
 *
 * Per rmw_wait holding a gated subscription (the caller's thread; no thread of our own):
 *  1. before the handshake, gated subscriptions stay out of the wait (polled every 20 ms);
 *  2. a probe (the real rmw_wait, timeout 0, gated subscriptions only) says which hold data;
 *  3. while tick j's bundle (clock + the inputs due at j) is incomplete, gated subscriptions
 *     without data may wake the wait, those with data stay out (and their QoS events, which
 *     share the reader's status condition), and none is reported ready;
 *  4. once complete, the bundle is handed out in rounds: a round is the longest run of the
 *     untaken subscriptions in the wanted order (clock, then the configured inputs in order)
 *     that the caller's wait set lists in increasing positions, so an executor that runs one
 *     wait's callbacks in wait-set order (rclpy, rclcpp single-threaded, a plain rcl loop) runs
 *     them in the wanted order. A round holding the whole bundle means a sim-time timer made
 *     due by the clock runs after every input (rcl decides timer readiness before the clock
 *     callback runs); with several rounds such a timer may run between two of them;
 *  5. when every message of the bundle was taken, the gate acknowledges j at the first wait
 *     of every thread it handed a round to that finds nothing else ready (timer guard
 *     conditions included): the program has run what the tick triggered and is idle.
 * Takes of a gated subscription outside its round return taken=false.
 * Gated subscriptions are made reliable and volatile (a best-effort one would lose messages).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "rmw/event.h"
#include "rmw/qos_profiles.h"
#include "rmw/rmw.h"
#include "std_msgs/msg/detail/int64_multi_array__struct.h"

#define GATE_ID "rmw_cosim_gate"
#define MAX_SUBS 256
#define MAX_EVENTS 1024
#define MAX_INPUTS 64
#define MAX_OUTPUTS 64
#define MAX_PUBS 1024
#define MAX_THREADS 16
#define READY_TICK (-1)
#define DISCOVERY_POLL_NS 20000000LL
#define BUSY_POLL_NS 1000000LL

#define HIDDEN __attribute__((visibility("hidden")))

/* ------------------------------------------------------------------ the real library */

/* Filled by cosim_gate_resolve(): the generated stubs jump through it (stubs.S). */
HIDDEN extern const char * const cosim_gate_names[];
HIDDEN extern const size_t cosim_gate_name_count;
HIDDEN void * cosim_gate_real[1024];

static void * real_lib;
static pthread_once_t resolve_once = PTHREAD_ONCE_INIT;

typedef rmw_ret_t (*wait_fn)(rmw_subscriptions_t *, rmw_guard_conditions_t *, rmw_services_t *,
                             rmw_clients_t *, rmw_events_t *, rmw_wait_set_t *,
                             const rmw_time_t *);
typedef rmw_subscription_t * (*create_sub_fn)(const rmw_node_t *,
                                              const rosidl_message_type_support_t *,
                                              const char *, const rmw_qos_profile_t *,
                                              const rmw_subscription_options_t *);
typedef rmw_ret_t (*destroy_sub_fn)(rmw_node_t *, rmw_subscription_t *);
typedef rmw_ret_t (*destroy_node_fn)(rmw_node_t *);
typedef rmw_ret_t (*event_init_fn)(rmw_event_t *, const rmw_subscription_t *, rmw_event_type_t);
typedef rmw_ret_t (*on_message_fn)(rmw_subscription_t *, rmw_event_callback_t, const void *);
typedef rmw_ret_t (*count_fn)(const rmw_subscription_t *, size_t *);
typedef rmw_publisher_t * (*create_pub_fn)(const rmw_node_t *,
                                           const rosidl_message_type_support_t *, const char *,
                                           const rmw_qos_profile_t *,
                                           const rmw_publisher_options_t *);
typedef rmw_ret_t (*destroy_pub_fn)(rmw_node_t *, rmw_publisher_t *);
typedef rmw_ret_t (*publish_fn)(const rmw_publisher_t *, const void *,
                                rmw_publisher_allocation_t *);
typedef rmw_ret_t (*publish_ser_fn)(const rmw_publisher_t *, const rmw_serialized_message_t *,
                                    rmw_publisher_allocation_t *);
typedef rmw_ret_t (*publish_loan_fn)(const rmw_publisher_t *, void *,
                                     rmw_publisher_allocation_t *);
typedef rmw_ret_t (*take_fn)(const rmw_subscription_t *, void *, bool *,
                             rmw_subscription_allocation_t *);
typedef rmw_ret_t (*take_info_fn)(const rmw_subscription_t *, void *, bool *,
                                  rmw_message_info_t *, rmw_subscription_allocation_t *);
typedef rmw_ret_t (*take_seq_fn)(const rmw_subscription_t *, size_t, rmw_message_sequence_t *,
                                 rmw_message_info_sequence_t *, size_t *,
                                 rmw_subscription_allocation_t *);
typedef rmw_ret_t (*take_ser_fn)(const rmw_subscription_t *, rmw_serialized_message_t *, bool *,
                                 rmw_subscription_allocation_t *);
typedef rmw_ret_t (*take_ser_info_fn)(const rmw_subscription_t *, rmw_serialized_message_t *,
                                      bool *, rmw_message_info_t *,
                                      rmw_subscription_allocation_t *);
typedef rmw_ret_t (*take_loan_fn)(const rmw_subscription_t *, void **, bool *,
                                  rmw_subscription_allocation_t *);
typedef rmw_ret_t (*take_loan_info_fn)(const rmw_subscription_t *, void **, bool *,
                                       rmw_message_info_t *, rmw_subscription_allocation_t *);
typedef rmw_ret_t (*take_dyn_fn)(const rmw_subscription_t *,
                                 rosidl_dynamic_typesupport_dynamic_data_t *, bool *,
                                 rmw_subscription_allocation_t *);
typedef rmw_ret_t (*take_dyn_info_fn)(const rmw_subscription_t *,
                                      rosidl_dynamic_typesupport_dynamic_data_t *, bool *,
                                      rmw_message_info_t *, rmw_subscription_allocation_t *);
typedef const rosidl_message_type_support_t * (*ts_fn)(void);

static struct {
  wait_fn wait;
  create_sub_fn create_sub;
  destroy_sub_fn destroy_sub;
  destroy_node_fn destroy_node;
  event_init_fn event_init;
  count_fn matched;
  on_message_fn on_message;
  create_pub_fn create_pub;
  destroy_pub_fn destroy_pub;
  publish_fn publish;
  publish_ser_fn publish_serialized;
  publish_loan_fn publish_loaned;
  take_fn take;
  take_ser_fn take_serialized;
  take_loan_fn take_loaned;
  take_dyn_fn take_dynamic;
  take_info_fn take_info;
  take_ser_info_fn take_serialized_info;
  take_loan_info_fn take_loaned_info;
  take_dyn_info_fn take_dynamic_info;
  take_seq_fn take_sequence;
} real;

static void die(const char * what)
{
  fprintf(stderr, "rmw_cosim_gate: fatal: %s\n", what);
  fflush(stderr);
  _exit(78);
}

static void * need(const char * name)
{
  void * sym = dlsym(real_lib, name);
  if (!sym) {
    char text[512];
    snprintf(text, sizeof text, "the real RMW library lacks %s", name);
    die(text);
  }
  return sym;
}

static void load_config(void);

static void resolve_now(void)
{
  const char * file = "librmw_fastrtps_cpp.so";
  real_lib = dlopen(file, RTLD_NOW | RTLD_LOCAL);
  if (!real_lib) {
    char text[1024];
    snprintf(text, sizeof text, "cannot load %s (%s): is its directory on LD_LIBRARY_PATH?",
             file, dlerror());
    die(text);
  }
  for (size_t i = 0; i < cosim_gate_name_count; ++i) {
    cosim_gate_real[i] = need(cosim_gate_names[i]);
  }
  real.wait = (wait_fn)need("rmw_wait");
  real.create_sub = (create_sub_fn)need("rmw_create_subscription");
  real.destroy_sub = (destroy_sub_fn)need("rmw_destroy_subscription");
  real.destroy_node = (destroy_node_fn)need("rmw_destroy_node");
  real.event_init = (event_init_fn)need("rmw_subscription_event_init");
  real.matched = (count_fn)need("rmw_subscription_count_matched_publishers");
  real.on_message = (on_message_fn)need("rmw_subscription_set_on_new_message_callback");
  real.create_pub = (create_pub_fn)need("rmw_create_publisher");
  real.destroy_pub = (destroy_pub_fn)need("rmw_destroy_publisher");
  real.publish = (publish_fn)need("rmw_publish");
  real.publish_serialized = (publish_ser_fn)need("rmw_publish_serialized_message");
  real.publish_loaned = (publish_loan_fn)need("rmw_publish_loaned_message");
  real.take = (take_fn)need("rmw_take");
  real.take_info = (take_info_fn)need("rmw_take_with_info");
  real.take_sequence = (take_seq_fn)need("rmw_take_sequence");
  real.take_serialized = (take_ser_fn)need("rmw_take_serialized_message");
  real.take_serialized_info = (take_ser_info_fn)need("rmw_take_serialized_message_with_info");
  real.take_loaned = (take_loan_fn)need("rmw_take_loaned_message");
  real.take_loaned_info = (take_loan_info_fn)need("rmw_take_loaned_message_with_info");
  real.take_dynamic = (take_dyn_fn)need("rmw_take_dynamic_message");
  real.take_dynamic_info = (take_dyn_info_fn)need("rmw_take_dynamic_message_with_info");
  load_config();
}

/* Called by the stubs (stubs.S) on their first use, and by every function of this file. */
HIDDEN void cosim_gate_resolve(void)
{
  pthread_once(&resolve_once, resolve_now);
}

/* ------------------------------------------------------------------ configuration */

typedef struct {
  char topic[512];  /* full name: prefix + own name */
  long period, phase, first;
} input_t;

static struct {
  int enabled;
  char prefix[256];
  char node[256];
  long period, start;
  input_t inputs[MAX_INPUTS];
  int n_inputs;
  char outputs[MAX_OUTPUTS][512];  /* resolved topic names, in the acknowledgement's order */
  int n_outputs;
} cfg;

static void load_config(void)
{
  const char * text = getenv("COSIM_RMW_GATE");
  if (!text || !*text) {
    return;
  }
  text = strdup(text);
  unsetenv("COSIM_RMW_GATE");  /* the program's own children are not fed */
  cfg.period = 1;
  char * copy = strdup(text);
  char * save = NULL;
  for (char * line = strtok_r(copy, "\n", &save); line; line = strtok_r(NULL, "\n", &save)) {
    char word[32], arg[256];
    long a = 0, b = 0, c = 0;
    if (sscanf(line, "%31s %255s", word, arg) < 2) {
      continue;
    }
    if (!strcmp(word, "prefix")) {
      snprintf(cfg.prefix, sizeof cfg.prefix, "%s", arg);
    } else if (!strcmp(word, "node")) {
      snprintf(cfg.node, sizeof cfg.node, "%s", arg);
    } else if (!strcmp(word, "period")) {
      cfg.period = atol(arg);
    } else if (!strcmp(word, "start")) {
      cfg.start = atol(arg);
    } else if (!strcmp(word, "input") && cfg.n_inputs < MAX_INPUTS &&
      sscanf(line, "%*s %*s %ld %ld %ld", &a, &b, &c) == 3)
    {
      input_t * in = &cfg.inputs[cfg.n_inputs++];
      snprintf(in->topic, sizeof in->topic, "%s%s", cfg.prefix, arg);
      in->period = a;
      in->phase = b;
      in->first = c;
    } else if (!strcmp(word, "output")) {
      if (cfg.n_outputs >= MAX_OUTPUTS) {
        die("COSIM_RMW_GATE: too many outputs");
      }
      snprintf(cfg.outputs[cfg.n_outputs++], sizeof cfg.outputs[0], "%s", arg);
    } else {
      die("COSIM_RMW_GATE: a line it does not understand");
    }
  }
  free(copy);
  if (cfg.prefix[0] != '/' || cfg.period < 1) {
    die("COSIM_RMW_GATE: needs an absolute prefix ending in / and a period >= 1");
  }
  cfg.enabled = 1;
}

/* ------------------------------------------------------------------ gate state */

typedef struct {
  const rmw_subscription_t * handle;
  const rmw_node_t * node;
  void * data;       /* what rcl puts in rmw_wait's subscription array */
  int rank;          /* 0: clock, 1..n: the configured input, -1: not fed */
  long created;
  int taken;         /* taken in the current bundle */
  int handed;        /* handed out in a round of the current bundle ... */
  pthread_t handed_to;  /* ... to this thread's wait */
  int alive;
} gsub_t;

static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static gsub_t subs[MAX_SUBS];
static int n_subs;
static long n_created;
static struct { const rmw_event_t * event; void * sub_data; } events[MAX_EVENTS];
static int n_events;
static long tick;
static int tick_set;
static int released;
static int ready_sent;
static rmw_publisher_t * ack_pub;
static const rmw_node_t * ack_node;
/* The program's publishers on its outputs, and what each output published since the last
 * acknowledgement (own lock: rmw_publish may run in any thread, ack() runs under mu). */
static pthread_mutex_t count_mu = PTHREAD_MUTEX_INITIALIZER;
static struct { const rmw_publisher_t * pub; int output; } out_pubs[MAX_PUBS];
static int n_out_pubs;
static int64_t counts[MAX_OUTPUTS];
/* The threads a round of the current bundle went to: 'returned' once the thread waits again
 * (an executor that waits in the thread that runs what the wait found has then run the
 * round's callbacks), 'idle' once such a wait found nothing else to run. */
static struct { pthread_t thread; int returned, idle; } involved[MAX_THREADS];
static int n_involved;

static gsub_t * find_sub(const void * data)
{
  for (int i = 0; i < n_subs; ++i) {
    if (subs[i].alive && subs[i].data == data) {
      return &subs[i];
    }
  }
  return NULL;
}

static int is_due(const gsub_t * s, long t)
{
  if (s->rank == 0) {
    return 1;
  }
  if (s->rank < 0) {
    return 0;
  }
  const input_t * in = &cfg.inputs[s->rank - 1];
  long d = t - in->phase;
  return t >= in->first && ((d % in->period) + in->period) % in->period == 0;
}

/* [-1] (ready), or [tick, messages per output since the last acknowledgement] */
static void ack(long value)
{
  if (!ack_pub) {
    return;
  }
  int64_t data[1 + MAX_OUTPUTS];
  size_t n = 1;
  data[0] = value;
  if (value != READY_TICK) {
    pthread_mutex_lock(&count_mu);
    for (int i = 0; i < cfg.n_outputs; ++i) {
      data[n++] = counts[i];
      counts[i] = 0;
    }
    pthread_mutex_unlock(&count_mu);
  }
  std_msgs__msg__Int64MultiArray msg;
  memset(&msg, 0, sizeof msg);  /* layout: no dimensions, offset 0 */
  msg.data.data = data;
  msg.data.size = msg.data.capacity = n;
  if (real.publish(ack_pub, &msg, NULL) != RMW_RET_OK) {
    die("cannot publish the acknowledgement");
  }
}

static int output_of(const rmw_publisher_t * pub)
{
  for (int i = 0; i < n_out_pubs; ++i) {
    if (out_pubs[i].pub == pub) {
      return out_pubs[i].output;
    }
  }
  return -1;
}

/* Count one message published (ret: what the real publish returned). */
static void published(const rmw_publisher_t * pub, rmw_ret_t ret)
{
  if (ret != RMW_RET_OK || !cfg.enabled || !pub) {
    return;
  }
  pthread_mutex_lock(&count_mu);
  int i = output_of(pub);
  if (i >= 0) {
    ++counts[i];
  }
  pthread_mutex_unlock(&count_mu);
}

static void ensure_ack_pub(void)
{
  if (ack_pub || !ack_node) {
    return;
  }
  void * lib = dlopen("libstd_msgs__rosidl_typesupport_c.so", RTLD_NOW | RTLD_LOCAL);
  if (!lib) {
    die("cannot load libstd_msgs__rosidl_typesupport_c.so for the acknowledgements");
  }
  ts_fn ts = (ts_fn)dlsym(
    lib,
    "rosidl_typesupport_c__get_message_type_support_handle__std_msgs__msg__Int64MultiArray");
  if (!ts) {
    die("libstd_msgs__rosidl_typesupport_c.so lacks std_msgs/msg/Int64MultiArray");
  }
  rmw_qos_profile_t qos = rmw_qos_profile_default;
  qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
  qos.depth = 1000;  /* a consumer may lag the program by the pipeline window */
  qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
  qos.durability = RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL;
  rmw_publisher_options_t options;
  memset(&options, 0, sizeof options);
  char topic[300];
  snprintf(topic, sizeof topic, "%staken", cfg.prefix);
  ack_pub = real.create_pub(ack_node, ts(), topic, &qos, &options);
  if (!ack_pub) {
    die("cannot create the acknowledgement publisher");
  }
}

static int involved_index(pthread_t self)
{
  for (int i = 0; i < n_involved; ++i) {
    if (pthread_equal(involved[i].thread, self)) {
      return i;
    }
  }
  return -1;
}

/* ------------------------------------------------------------------ rmw functions */

const char * rmw_get_implementation_identifier(void)
{
  return GATE_ID;
}

rmw_subscription_t * rmw_create_subscription(
  const rmw_node_t * node, const rosidl_message_type_support_t * type_support,
  const char * topic_name, const rmw_qos_profile_t * qos_policies,
  const rmw_subscription_options_t * subscription_options)
{
  cosim_gate_resolve();
  size_t plen = strlen(cfg.prefix);
  int gated = cfg.enabled && topic_name && qos_policies && !strncmp(topic_name, cfg.prefix, plen);
  if (!gated) {
    return real.create_sub(node, type_support, topic_name, qos_policies, subscription_options);
  }
  rmw_qos_profile_t qos = *qos_policies;
  qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;  /* never lose a fed message */
  qos.durability = RMW_QOS_POLICY_DURABILITY_VOLATILE;    /* the feeder's writers are volatile */
  if (qos.history == RMW_QOS_POLICY_HISTORY_KEEP_LAST && qos.depth < 1) {
    qos.depth = 1;
  }
  rmw_subscription_t * sub = real.create_sub(node, type_support, topic_name, &qos,
                                             subscription_options);
  if (!sub) {
    return NULL;
  }
  pthread_mutex_lock(&mu);
  int rank = -1;
  if (!strcmp(topic_name + plen, "clock")) {
    rank = 0;
  }
  for (int i = 0; i < cfg.n_inputs && rank < 0; ++i) {
    if (!strcmp(cfg.inputs[i].topic, topic_name)) {
      rank = i + 1;
    }
  }
  if (n_subs >= MAX_SUBS) {
    die("too many gated subscriptions");
  }
  gsub_t * s = &subs[n_subs++];
  memset(s, 0, sizeof *s);
  s->handle = sub;
  s->node = node;
  s->data = sub->data;
  s->rank = rank;
  s->created = n_created++;
  s->alive = 1;
  /* a subscription made while its tick is being handed out waits for the next tick */
  s->taken = released;
  if (!ack_node) {
    ack_node = node;
  }
  pthread_mutex_unlock(&mu);
  return sub;
}

rmw_ret_t rmw_destroy_subscription(rmw_node_t * node, rmw_subscription_t * subscription)
{
  cosim_gate_resolve();
  if (subscription) {
    pthread_mutex_lock(&mu);
    gsub_t * s = find_sub(subscription->data);
    if (s) {
      s->alive = 0;
      for (int i = 0; i < n_events; ++i) {
        if (events[i].sub_data == s->data) {
          events[i] = events[--n_events];
          --i;
        }
      }
    }
    pthread_mutex_unlock(&mu);
  }
  return real.destroy_sub(node, subscription);
}

rmw_ret_t rmw_destroy_node(rmw_node_t * node)
{
  cosim_gate_resolve();
  pthread_mutex_lock(&mu);
  if (node && node == ack_node) {
    if (ack_pub) {
      real.destroy_pub(node, ack_pub);
    }
    ack_pub = NULL;
    ack_node = NULL;
    for (int i = 0; i < n_subs; ++i) {
      if (subs[i].alive && subs[i].node != node) {
        ack_node = subs[i].node;  /* the acknowledgements go on from another node */
        break;
      }
    }
  }
  pthread_mutex_unlock(&mu);
  return real.destroy_node(node);
}

rmw_ret_t rmw_subscription_event_init(
  rmw_event_t * rmw_event, const rmw_subscription_t * subscription, rmw_event_type_t event_type)
{
  cosim_gate_resolve();
  rmw_ret_t ret = real.event_init(rmw_event, subscription, event_type);
  if (ret == RMW_RET_OK && subscription) {
    pthread_mutex_lock(&mu);
    if (find_sub(subscription->data)) {
      int i = 0;
      while (i < n_events && events[i].event != rmw_event) {
        ++i;
      }
      if (i == n_events && n_events < MAX_EVENTS) {
        ++n_events;
      }
      if (i < MAX_EVENTS) {
        events[i].event = rmw_event;
        events[i].sub_data = subscription->data;
      }
    }
    pthread_mutex_unlock(&mu);
  }
  return ret;
}

static void * event_owner(const void * event)
{
  for (int i = 0; i < n_events; ++i) {
    if (events[i].event == event) {
      return events[i].sub_data;
    }
  }
  return NULL;
}

/* ------------------------------------------------------------------ publishers */

rmw_publisher_t * rmw_create_publisher(
  const rmw_node_t * node, const rosidl_message_type_support_t * type_support,
  const char * topic_name, const rmw_qos_profile_t * qos_profile,
  const rmw_publisher_options_t * publisher_options)
{
  cosim_gate_resolve();
  rmw_publisher_t * pub = real.create_pub(node, type_support, topic_name, qos_profile,
                                          publisher_options);
  if (!pub || !cfg.enabled || !topic_name) {
    return pub;
  }
  for (int i = 0; i < cfg.n_outputs; ++i) {
    if (!strcmp(cfg.outputs[i], topic_name)) {
      pthread_mutex_lock(&count_mu);
      if (n_out_pubs >= MAX_PUBS) {
        die("too many publishers on the program's outputs");
      }
      out_pubs[n_out_pubs].pub = pub;
      out_pubs[n_out_pubs].output = i;
      ++n_out_pubs;
      pthread_mutex_unlock(&count_mu);
      break;
    }
  }
  return pub;
}

rmw_ret_t rmw_destroy_publisher(rmw_node_t * node, rmw_publisher_t * publisher)
{
  cosim_gate_resolve();
  pthread_mutex_lock(&count_mu);
  for (int i = 0; i < n_out_pubs; ++i) {
    if (out_pubs[i].pub == publisher) {
      out_pubs[i] = out_pubs[--n_out_pubs];
      break;
    }
  }
  pthread_mutex_unlock(&count_mu);
  return real.destroy_pub(node, publisher);
}

rmw_ret_t rmw_publish(const rmw_publisher_t * publisher, const void * ros_message,
                      rmw_publisher_allocation_t * allocation)
{
  cosim_gate_resolve();
  rmw_ret_t ret = real.publish(publisher, ros_message, allocation);
  published(publisher, ret);
  return ret;
}

rmw_ret_t rmw_publish_serialized_message(const rmw_publisher_t * publisher,
                                         const rmw_serialized_message_t * serialized_message,
                                         rmw_publisher_allocation_t * allocation)
{
  cosim_gate_resolve();
  rmw_ret_t ret = real.publish_serialized(publisher, serialized_message, allocation);
  published(publisher, ret);
  return ret;
}

rmw_ret_t rmw_publish_loaned_message(const rmw_publisher_t * publisher, void * ros_message,
                                     rmw_publisher_allocation_t * allocation)
{
  cosim_gate_resolve();
  rmw_ret_t ret = real.publish_loaned(publisher, ros_message, allocation);
  published(publisher, ret);
  return ret;
}

/* ------------------------------------------------------------------ takes */

/* Whether a take from this subscription may reach the middleware now. */
static int take_allowed(const rmw_subscription_t * sub, gsub_t ** gated)
{
  *gated = NULL;
  if (!cfg.enabled || !sub) {
    return 1;
  }
  pthread_mutex_lock(&mu);
  gsub_t * s = find_sub(sub->data);
  int ok = 1;
  if (s) {
    *gated = s;
    ok = ready_sent && released && is_due(s, tick) && !s->taken;
  }
  pthread_mutex_unlock(&mu);
  return ok;
}

static void taken_now(gsub_t * s, int taken)
{
  if (s && taken) {
    pthread_mutex_lock(&mu);
    s->taken = 1;
    int elsewhere = s->handed && !pthread_equal(s->handed_to, pthread_self());
    pthread_mutex_unlock(&mu);
    if (elsewhere) {
      /* rclpy's MultiThreadedExecutor: its worker threads take and run callbacks while the
       * waiting thread goes on; nothing at the RMW layer says when such a callback ends */
      die("a fed message was taken in another thread than the one whose wait handed it out "
          "(an executor that runs callbacks in worker threads, like rclpy's "
          "MultiThreadedExecutor): the RMW gate cannot tell when its callbacks end. Use a "
          "single-threaded executor, rclcpp's MultiThreadedExecutor, or for rclpy the Python "
          "gate (params.gate: python)");
    }
  }
}

rmw_ret_t rmw_subscription_set_on_new_message_callback(
  rmw_subscription_t * subscription, rmw_event_callback_t callback, const void * user_data)
{
  cosim_gate_resolve();
  if (callback && subscription && cfg.enabled) {
    pthread_mutex_lock(&mu);
    gsub_t * s = find_sub(subscription->data);
    pthread_mutex_unlock(&mu);
    if (s) {
      die("a fed subscription asked for new-message callbacks (an events executor, like "
          "rclcpp's EventsExecutor, which never waits): the RMW gate serves executors that "
          "wait (rmw_wait); use a single- or multi-threaded executor");
    }
  }
  return real.on_message(subscription, callback, user_data);
}

#define GATED_TAKE(fn, call) \
  do { \
    cosim_gate_resolve(); \
    gsub_t * g; \
    if (!take_allowed(subscription, &g)) { \
      *taken = false; \
      return RMW_RET_OK; \
    } \
    rmw_ret_t ret = call; \
    if (ret == RMW_RET_OK) { \
      taken_now(g, *taken); \
    } \
    return ret; \
  } while (0)

rmw_ret_t rmw_take(const rmw_subscription_t * subscription, void * ros_message, bool * taken,
                   rmw_subscription_allocation_t * allocation)
{
  GATED_TAKE(take, real.take(subscription, ros_message, taken, allocation));
}

rmw_ret_t rmw_take_with_info(const rmw_subscription_t * subscription, void * ros_message,
                             bool * taken, rmw_message_info_t * message_info,
                             rmw_subscription_allocation_t * allocation)
{
  GATED_TAKE(take_info, real.take_info(subscription, ros_message, taken, message_info,
                                       allocation));
}

rmw_ret_t rmw_take_serialized_message(const rmw_subscription_t * subscription,
                                      rmw_serialized_message_t * serialized_message,
                                      bool * taken, rmw_subscription_allocation_t * allocation)
{
  GATED_TAKE(take_serialized, real.take_serialized(subscription, serialized_message, taken,
                                                   allocation));
}

rmw_ret_t rmw_take_serialized_message_with_info(
  const rmw_subscription_t * subscription, rmw_serialized_message_t * serialized_message,
  bool * taken, rmw_message_info_t * message_info, rmw_subscription_allocation_t * allocation)
{
  GATED_TAKE(take_serialized_info, real.take_serialized_info(
      subscription, serialized_message, taken, message_info, allocation));
}

rmw_ret_t rmw_take_loaned_message(const rmw_subscription_t * subscription,
                                  void ** loaned_message, bool * taken,
                                  rmw_subscription_allocation_t * allocation)
{
  GATED_TAKE(take_loaned, real.take_loaned(subscription, loaned_message, taken, allocation));
}

rmw_ret_t rmw_take_loaned_message_with_info(
  const rmw_subscription_t * subscription, void ** loaned_message, bool * taken,
  rmw_message_info_t * message_info, rmw_subscription_allocation_t * allocation)
{
  GATED_TAKE(take_loaned_info, real.take_loaned_info(subscription, loaned_message, taken,
                                                     message_info, allocation));
}

rmw_ret_t rmw_take_dynamic_message(const rmw_subscription_t * subscription,
                                   rosidl_dynamic_typesupport_dynamic_data_t * dynamic_message,
                                   bool * taken,
                                   rmw_subscription_allocation_t * allocation)
{
  GATED_TAKE(take_dynamic, real.take_dynamic(subscription, dynamic_message, taken, allocation));
}

rmw_ret_t rmw_take_dynamic_message_with_info(
  const rmw_subscription_t * subscription,
  rosidl_dynamic_typesupport_dynamic_data_t * dynamic_message, bool * taken,
  rmw_message_info_t * message_info, rmw_subscription_allocation_t * allocation)
{
  GATED_TAKE(take_dynamic_info, real.take_dynamic_info(subscription, dynamic_message, taken,
                                                       message_info, allocation));
}

rmw_ret_t rmw_take_sequence(const rmw_subscription_t * subscription, size_t count,
                            rmw_message_sequence_t * message_sequence,
                            rmw_message_info_sequence_t * message_info_sequence,
                            size_t * taken, rmw_subscription_allocation_t * allocation)
{
  cosim_gate_resolve();
  gsub_t * g;
  if (!take_allowed(subscription, &g)) {
    *taken = 0;
    return RMW_RET_OK;
  }
  if (g) {
    count = 1;  /* one message per gated subscription and tick */
  }
  rmw_ret_t ret = real.take_sequence(subscription, count, message_sequence,
                                     message_info_sequence, taken, allocation);
  if (ret == RMW_RET_OK) {
    taken_now(g, *taken > 0);
  }
  return ret;
}

/* ------------------------------------------------------------------ wait */

/* What one real wait holds, built from the caller's arrays (which rmw_wait compacts: no NULL
 * entries in its input). */
typedef struct {
  size_t n;
  void ** from;      /* the caller's entries */
  char * include;    /* goes into the real wait */
  char * visible;    /* may be reported ready to the caller */
  void ** tmp;       /* compacted copy handed to the real wait */
} lane_t;

static void lane_init(lane_t * l, size_t n, void ** from)
{
  l->n = n;
  l->from = from;
  l->include = calloc(n + 1, 1);
  l->visible = calloc(n + 1, 1);
  l->tmp = calloc(n + 1, sizeof(void *));
  for (size_t i = 0; i < n; ++i) {
    l->include[i] = l->visible[i] = 1;
  }
}

static size_t lane_pack(lane_t * l)
{
  size_t k = 0;
  for (size_t i = 0; i < l->n; ++i) {
    if (l->include[i]) {
      l->tmp[k++] = l->from[i];
    }
  }
  return k;
}

/* Writes the real wait's result back into the caller's array; returns how many are ready. */
static size_t lane_unpack(lane_t * l, int write)
{
  size_t k = 0, ready = 0;
  for (size_t i = 0; i < l->n; ++i) {
    void * out = NULL;
    if (l->include[i]) {
      if (l->tmp[k] && l->visible[i]) {
        out = l->from[i];
        ++ready;
      }
      ++k;
    }
    if (write) {
      l->from[i] = out;
    }
  }
  return ready;
}

static void lane_free(lane_t * l)
{
  free(l->include);
  free(l->visible);
  free(l->tmp);
}

typedef struct {
  lane_t s, g, sv, c, e;
  void ** orig_subs;  /* the caller's subscription array, saved before any real wait */
} waitplan_t;

/* One real wait over the planned entries; returns its code and how many visible are ready. */
static rmw_ret_t planned_wait(waitplan_t * p, rmw_wait_set_t * ws, const rmw_time_t * timeout,
                              size_t * ready, int write)
{
  rmw_subscriptions_t s = {lane_pack(&p->s), p->s.tmp};
  rmw_guard_conditions_t g = {lane_pack(&p->g), p->g.tmp};
  rmw_services_t sv = {lane_pack(&p->sv), p->sv.tmp};
  rmw_clients_t c = {lane_pack(&p->c), p->c.tmp};
  rmw_events_t e = {lane_pack(&p->e), p->e.tmp};
  rmw_ret_t ret = real.wait(&s, &g, &sv, &c, &e, ws, timeout);
  size_t n = 0;
  if (ret == RMW_RET_OK || ret == RMW_RET_TIMEOUT) {
    n += lane_unpack(&p->s, write);
    n += lane_unpack(&p->g, write);
    n += lane_unpack(&p->sv, write);
    n += lane_unpack(&p->c, write);
    n += lane_unpack(&p->e, write);
  }
  *ready = n;
  return ret;
}

/* Which gated subscriptions hold data: the real wait, timeout 0, on them alone. */
static void probe(rmw_wait_set_t * ws, char * present)
{
  void * tmp[MAX_SUBS];
  int idx[MAX_SUBS];
  size_t k = 0;
  for (int i = 0; i < n_subs; ++i) {
    present[i] = 0;
    if (subs[i].alive) {
      idx[k] = i;
      tmp[k++] = subs[i].data;
    }
  }
  if (!k) {
    return;
  }
  rmw_subscriptions_t s = {k, tmp};
  rmw_guard_conditions_t g = {0, NULL};
  rmw_services_t sv = {0, NULL};
  rmw_clients_t c = {0, NULL};
  rmw_events_t e = {0, NULL};
  rmw_time_t zero = {0, 0};
  rmw_ret_t ret = real.wait(&s, &g, &sv, &c, &e, ws, &zero);
  if (ret != RMW_RET_OK && ret != RMW_RET_TIMEOUT) {
    die("the probe of the fed subscriptions failed");
  }
  for (size_t j = 0; j < k; ++j) {
    present[idx[j]] = tmp[j] != NULL;
  }
}

static int by_rank(const void * a, const void * b)
{
  const gsub_t * x = *(gsub_t * const *)a;
  const gsub_t * y = *(gsub_t * const *)b;
  if (x->rank != y->rank) {
    return x->rank < y->rank ? -1 : 1;
  }
  return x->created < y->created ? -1 : (x->created > y->created);
}

static const rmw_time_t * cap(const rmw_time_t * timeout, rmw_time_t * storage, long long ns)
{
  if (timeout) {
    long long t = (long long)timeout->sec * 1000000000LL + (long long)timeout->nsec;
    if (t <= ns) {
      return timeout;
    }
  }
  storage->sec = ns / 1000000000LL;
  storage->nsec = ns % 1000000000LL;
  return storage;
}

rmw_ret_t rmw_wait(rmw_subscriptions_t * subscriptions, rmw_guard_conditions_t * guard_conditions,
                   rmw_services_t * services, rmw_clients_t * clients, rmw_events_t * events_in,
                   rmw_wait_set_t * wait_set, const rmw_time_t * wait_timeout)
{
  cosim_gate_resolve();
  size_t ns = subscriptions ? subscriptions->subscriber_count : 0;
  if (!cfg.enabled || !ns) {
    return real.wait(subscriptions, guard_conditions, services, clients, events_in, wait_set,
                     wait_timeout);
  }
  pthread_mutex_lock(&mu);
  gsub_t ** at = calloc(ns, sizeof(gsub_t *));  /* caller position -> gated subscription */
  int any = 0;
  for (size_t i = 0; i < ns; ++i) {
    at[i] = find_sub(subscriptions->subscribers[i]);
    any |= at[i] != NULL;
  }
  if (!any) {
    pthread_mutex_unlock(&mu);
    free(at);
    return real.wait(subscriptions, guard_conditions, services, clients, events_in, wait_set,
                     wait_timeout);
  }
  waitplan_t p;
  lane_init(&p.s, ns, subscriptions->subscribers);
  lane_init(&p.g, guard_conditions ? guard_conditions->guard_condition_count : 0,
            guard_conditions ? guard_conditions->guard_conditions : NULL);
  lane_init(&p.sv, services ? services->service_count : 0, services ? services->services : NULL);
  lane_init(&p.c, clients ? clients->client_count : 0, clients ? clients->clients : NULL);
  lane_init(&p.e, events_in ? events_in->event_count : 0, events_in ? events_in->events : NULL);
  const rmw_time_t * timeout = wait_timeout;
  rmw_time_t storage;
  char present[MAX_SUBS];
  pthread_t self = pthread_self();
  if (!tick_set) {
    tick = cfg.start;
    tick_set = 1;
  }
  ensure_ack_pub();
  int me = involved_index(self);
  if (me >= 0) {
    involved[me].returned = 1;
  }

  /* every gated entry (and its events) out unless the plan puts it in */
  for (size_t i = 0; i < ns; ++i) {
    if (at[i]) {
      p.s.include[i] = 0;
      p.s.visible[i] = 0;
    }
  }

  if (!ready_sent) {
    int all = 1;
    for (int i = 0; i < n_subs; ++i) {
      size_t count = 0;
      if (subs[i].alive && (real.matched(subs[i].handle, &count) != RMW_RET_OK || !count)) {
        all = 0;
      }
    }
    if (all) {
      ready_sent = 1;
      ack(READY_TICK);
    } else {
      timeout = cap(wait_timeout, &storage, DISCOVERY_POLL_NS);
    }
  }

  int idle_probe = 0;
  while (ready_sent) {
    probe(wait_set, present);
    if (!released) {
      int due = 0, complete = 1;
      for (int i = 0; i < n_subs; ++i) {
        if (subs[i].alive && is_due(&subs[i], tick)) {
          ++due;
          complete &= present[i];
        }
      }
      if (due && complete) {
        released = 1;
        n_involved = 0;
        for (int i = 0; i < n_subs; ++i) {
          subs[i].taken = !(subs[i].alive && is_due(&subs[i], tick));
          subs[i].handed = 0;
        }
      } else {
        /* incomplete: gated subscriptions without data may wake us, none is handed out */
        for (size_t i = 0; i < ns; ++i) {
          if (at[i]) {
            p.s.include[i] = !present[at[i] - subs];
          }
        }
        break;
      }
    }
    gsub_t * remaining[MAX_SUBS];
    int nr = 0;
    for (int i = 0; i < n_subs; ++i) {
      if (subs[i].alive && !subs[i].taken && is_due(&subs[i], tick)) {
        if (!present[i]) {
          subs[i].taken = 1;  /* its message was taken outside any wait */
          continue;
        }
        remaining[nr++] = &subs[i];
      }
    }
    /* one thread at a time: a round goes out once every other thread that had one has
     * come back to wait, so a round's callbacks never overlap another's */
    int others_back = 1;
    for (int i = 0; i < n_involved; ++i) {
      if (!pthread_equal(involved[i].thread, self)) {
        others_back &= involved[i].returned;
      }
    }
    if (nr) {
      qsort(remaining, nr, sizeof remaining[0], by_rank);
      long last = -1;
      int handed = 0;
      for (int r = 0; r < nr && others_back; ++r) {
        long pos = -1;
        for (size_t i = 0; i < ns; ++i) {
          if (at[i] == remaining[r]) {
            pos = (long)i;
            break;
          }
        }
        if (pos < 0 || pos < last) {
          break;
        }
        p.s.include[pos] = p.s.visible[pos] = 1;
        remaining[r]->handed = 1;
        remaining[r]->handed_to = self;
        last = pos;
        ++handed;
      }
      if (handed) {
        int k = involved_index(self);
        if (k < 0 && n_involved < MAX_THREADS) {
          k = n_involved++;
          involved[k].thread = self;
        }
        if (k >= 0) {
          involved[k].returned = 0;
          involved[k].idle = 0;
        }
      } else {
        timeout = cap(wait_timeout, &storage, BUSY_POLL_NS);  /* another thread's turn */
      }
      break;
    }
    /* the whole bundle is taken: acknowledge once every thread that ran part of it is idle */
    int k = involved_index(self);
    if (k >= 0 && !involved[k].idle && !idle_probe) {
      idle_probe = 1;
      break;  /* a zero-timeout wait over everything else first (below) */
    }
    int all_idle = 1;
    for (int i = 0; i < n_involved; ++i) {
      all_idle &= involved[i].idle;
    }
    if (!all_idle) {
      break;  /* another thread is still running callbacks: it acknowledges */
    }
    ack(tick);
    tick += cfg.period;
    released = 0;
    n_involved = 0;
  }

  /* events of gated subscriptions holding data would wake the wait at once: keep them out */
  for (size_t i = 0; i < p.e.n; ++i) {
    void * owner = event_owner(p.e.from[i]);
    gsub_t * s = owner ? find_sub(owner) : NULL;
    if (s && (!ready_sent || present[s - subs])) {
      int handed = 0;
      for (size_t j = 0; j < ns; ++j) {
        handed |= at[j] == s && p.s.visible[j];
      }
      p.e.include[i] = handed;
    }
  }
  pthread_mutex_unlock(&mu);

  rmw_ret_t ret;
  size_t ready = 0;
  if (idle_probe) {
    rmw_time_t zero = {0, 0};
    ret = planned_wait(&p, wait_set, &zero, &ready, 0);
    if (ret != RMW_RET_OK && ret != RMW_RET_TIMEOUT) {
      goto done;  /* the middleware's error, as it is */
    }
    if (ready) {
      lane_unpack(&p.s, 1);
      lane_unpack(&p.g, 1);
      lane_unpack(&p.sv, 1);
      lane_unpack(&p.c, 1);
      lane_unpack(&p.e, 1);
      goto done;
    }
    /* idle: mark it, acknowledge if every thread is, and wait for the next tick */
    pthread_mutex_lock(&mu);
    int k = involved_index(self);
    if (k >= 0) {
      involved[k].idle = 1;
    }
    int all_idle = 1;
    for (int i = 0; i < n_involved; ++i) {
      all_idle &= involved[i].idle;
    }
    if (released && all_idle) {
      ack(tick);
      tick += cfg.period;
      released = 0;
      n_involved = 0;
    }
    /* the next tick's messages (not fed yet) wake the wait */
    for (size_t i = 0; i < ns; ++i) {
      if (at[i]) {
        p.s.include[i] = 1;
        p.s.visible[i] = 0;
      }
    }
    pthread_mutex_unlock(&mu);
  }
  ret = planned_wait(&p, wait_set, timeout, &ready, 1);
  if (ret == RMW_RET_TIMEOUT && timeout != wait_timeout) {
    ret = RMW_RET_OK;  /* our poll, not the caller's timeout */
  }
done:
  lane_free(&p.s);
  lane_free(&p.g);
  lane_free(&p.sv);
  lane_free(&p.c);
  lane_free(&p.e);
  free(at);
  return ret;
}
